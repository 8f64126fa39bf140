MODULE PickPlace
!----------------------------------------------------------------------
! Pick and place: parts from the infeed fixture into a 2 x 2 tray.
! Gripper: tGripper (125 mm).  Tray: wobjTray, turned 30 deg on the table.
! Taught 2024-03-14, cell 3.
!----------------------------------------------------------------------

    ! Gripper: TCP 125 mm along the flange axis, 1.2 kg
    PERS tooldata tGripper:=[TRUE,[[0,0,125],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];

    ! Tray: user frame on the table corner, object frame on the tray's first pocket
    PERS wobjdata wobjTray:=[FALSE,TRUE,"",[[420,-180,180],[0.965925826,0,0,0.258819045]],
                                          [[20,10,0],[1,0,0,0]]];

    CONST jointtarget jHome:=[[0,-20,30,0,80,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

    ! Infeed fixture, robot base frame
    CONST robtarget pAbovePick:=[[450,150,420],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pPick:=[[450.5,150.25,252.75],[0,0,1,0],[0,0,0,0],
                            [9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

    ! Tray pockets, wobjTray
    PERS robtarget pAbovePlace:=[[60,40,120],[0,0.707106781,0.707106781,0],[-1,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    PERS robtarget pPlace:=[[60,40,30],[0,0.707106781,0.707106781,0],[-1,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    ! Old tray's pocket, kept for the next changeover
    CONST robtarget pPlaceOld:=[[140,40,30],[0,0.707106781,0.707106781,0],[-1,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

    VAR num nPart:=0;
    VAR bool bPartOk:=FALSE;

    PROC main()
        MoveAbsJ jHome\NoEOffs, v1000, z50, tGripper;
        WHILE nPart < 4 DO
            PickPart;
            PlacePart;
            Incr nPart;
        ENDWHILE

        ! Park out of the operator's way
        MoveAbsJ [[-30,-25,35,0,75,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]\NoEOffs, v500, fine, tool0;
        TPWrite "Tray full, parts: "\Num:=nPart;
    ENDPROC

    PROC PickPart()
        MoveJ pAbovePick, v1000, z50, tGripper;
        MoveL pPick, v200, fine, tGripper;
        SetDO doGripper, 1;
        WaitTime 0.3;
        bPartOk:=DInput(diPartPresent) = 1;
        ! Lift straight up before turning to the tray
        MoveL Offs(pPick,0,0,150), v500, z20, tGripper;
    ENDPROC

    PROC PlacePart()
        MoveJ pAbovePlace, v1000, z50, tGripper\WObj:=wobjTray;
        MoveL pPlace, v100, fine, tGripper\WObj:=wobjTray;
        SetDO doGripper, 0;
        WaitTime 0.2;
        MoveL RelTool(pPlace,0,0,-90), v500, z20, tGripper\WObj:=wobjTray;
        ! Swing back over the infeed on an arc
        MoveC [[300,50,380],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], pAbovePick, v500, z50, tGripper;
    ENDPROC
ENDMODULE

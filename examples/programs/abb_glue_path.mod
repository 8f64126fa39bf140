MODULE GluePath
    !*****************************************************************
    ! Glue bead around the cover plate (160 x 120 mm, corner radius 20).
    ! The gun is tilted 20 deg about its y axis; the plate lies in
    ! fixture wobjFixture, turned 10 deg about Z.
    !*****************************************************************

    PERS tooldata tGlueGun:=[TRUE,[[-45.5,0,162.25],[0.984807753,0,0.173648178,0]],
        [2.4,[-10,0,80],[1,0,0,0],0.01,0.01,0.01]];
    PERS wobjdata wobjFixture:=[FALSE,TRUE,"",[[380,-90,150],[1,0,0,0]],[[12.5,8,0],[0.996194698,0,0,0.087155743]]];

    ! Bead speed and the delay for the glue to start flowing
    VAR speeddata vGlue:=[60,30,5000,1000];
    PERS num nBeadDelay:=0.15;

    CONST jointtarget jSafe:=[[10,-10,20,0,60,10],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

    ! Bead, fixture object frame; the gun points down (q = [0,0,-1,0])
    CONST robtarget pStart:=[[20,0,10],[0,0,-1,0],[-1,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pEdge1:=[[140,0,10],[0,0,-1,0],[-1,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pArc1:=[[154.142136,5.857864,10],[0,-0.195090322,-0.98078528,0],[-1,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pEdge2:=[[160,20,10],[0,-0.382683432,-0.923879533,0],[0,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pEdge3:=[[160,100,10],
                             [0,-0.382683432,-0.923879533,0],
                             [0,-1,0,0],
                             [9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pArc2:=[[154.142136,114.142136,10],[0,-0.55557023,-0.831469612,0],[0,-1,1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pEdge4:=[[140,120,10],[0,-0.707106781,-0.707106781,0],[0,-1,1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pEnd:=[[20,120,10],[0,-0.707106781,-0.707106781,0],[0,-1,1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

    PROC main()
        MoveAbsJ jSafe\NoEOffs, v1000, z50, tGlueGun;
        ! Approach 50 mm above the start
        MoveJ Offs(pStart,0,0,50), v1000, z20, tGlueGun\WObj:=wobjFixture;
        MoveL pStart, v200, fine, tGlueGun\WObj:=wobjFixture;
        SetDO doGlueOn, 1;
        WaitTime nBeadDelay;

        MoveL pEdge1, vGlue, z5, tGlueGun\WObj:=wobjFixture;
        MoveC pArc1, pEdge2, vGlue, z5, tGlueGun\WObj:=wobjFixture;
        MoveL pEdge3, vGlue\V:=80, z5, tGlueGun\WObj:=wobjFixture;
        MoveC pArc2, pEdge4, vGlue, z5, tGlueGun\WObj:=wobjFixture;
        ! Glue off exactly at the end point
        MoveLDO pEnd, vGlue, fine, tGlueGun\WObj:=wobjFixture, doGlueOn, 0;

        ! Retract, then home
        MoveL \Conc, [[20,140,60],[0,-0.707106781,-0.707106781,0],[0,-1,1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], v500\T:=1.5, z20, tGlueGun\WObj:=wobjFixture;
        MoveAbsJ jSafe, v1000, fine, tGlueGun;
    ENDPROC
ENDMODULE

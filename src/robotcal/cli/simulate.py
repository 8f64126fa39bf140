"""``robotcal simulate SCENARIO --out CAPTURE.csv``: a synthetic Circle Point (or validation) capture, or with
``--free-poses N`` / ``--poses CSV`` a capture of several flange targets at free poses (docs/cli.md)."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli._common import (
    BYTES_PER_POSE,
    SEED_BOUND,
    Force,
    ScenarioArgument,
    app_command,
    check_memory,
    command_app,
    console,
)
from robotcal.errors import InputError
from robotcal.io.results.output import existing_inputs, result_file

app = command_app()


# The options of `simulate` that take several lines, declared once here (the command reads as a list of its options).
_Seed = Annotated[
    int | None,
    typer.Option(
        min=0,
        max=SEED_BOUND - 1,
        help="Seed of the random draws (default: the scenario's capture.seed, or validation.seed).",
    ),
]
_TrueParams = Annotated[
    Path | None, typer.Option("--true-params", help="Parameter JSON of the 'real' robot (default: nominal).")
]
_TruthOut = Annotated[
    Path | None,
    typer.Option(
        "--truth-out",
        help="Perturb the nominal robot per the scenario's [truth] table, simulate that robot and write it here.",
    ),
]
_Validation = Annotated[
    bool,
    typer.Option(
        "--validation", help="Simulate a validation capture at random poses ([validation] table) instead."
    ),
]
_FreePoses = Annotated[
    int | None,
    typer.Option(
        "--free-poses",
        min=1,
        help="Simulate this many random poses (within the joint limits less [validation].margin_deg), each "
        "measured on every target of --targets: a capture with a target column, no circles.",
    ),
]
_Poses = Annotated[
    Path | None,
    typer.Option("--poses", help="Like --free-poses, at the poses of this pose CSV (q1..qN, controller deg)."),
]
_Targets = Annotated[
    str | None,
    typer.Option(
        "--targets",
        help='Flange targets measured at each free pose, "T1,T2,T3" (default: every flange target the scenario '
        "declares: [[targets]], then [validation]'s as 'validation').",
    ),
]
_TargetsMm = Annotated[
    str | None,
    typer.Option(
        "--targets-mm",
        help='True flange offsets "T1=x,y,z;T2=x,y,z" [mm] of the simulated robot: needed for targets declared '
        'flange_mm = "unknown" (unless --true-params has them), else the declared offsets.',
    ),
]


@app_command(app)
def simulate(
    scenario: ScenarioArgument,
    out: Annotated[Path, typer.Option("--out", "-o", help="Capture CSV to write.")],
    seed: _Seed = None,
    true_params: _TrueParams = None,
    truth_out: _TruthOut = None,
    validation: _Validation = False,
    free_poses: _FreePoses = None,
    poses: _Poses = None,
    targets: _Targets = None,
    targets_mm: _TargetsMm = None,
    force: Force = False,
) -> None:
    """Simulate the scenario's capture and write it as a capture CSV."""
    from robotcal.io.schema.scenario import ValidationTable, load_scenario

    loaded = load_scenario(scenario)
    if true_params is not None and truth_out is not None:
        raise InputError("give either --true-params (an existing truth) or --truth-out (a new perturbed truth)")
    free = None
    if free_poses is not None or poses is not None:
        if free_poses is not None and poses is not None:
            raise InputError("give --free-poses N (random poses) or --poses CSV (given poses), not both")
        if validation:
            raise InputError("--validation simulates the [validation] table; --free-poses/--poses replace it")
        free = (free_poses, poses, targets, targets_mm)
    elif targets is not None or targets_mm is not None:
        raise InputError("--targets and --targets-mm go with --free-poses N or --poses CSV")
    inputs = existing_inputs(scenario, *loaded.files, true_params, poses)
    if validation or free_poses is not None:
        count = free_poses if not validation and free_poses is not None else (loaded.validation or ValidationTable()).poses
        check_memory(
            f"a capture of {count:,} poses",
            count * float(BYTES_PER_POSE) * (1 if validation else max(1, len(loaded.targets))),
            "lower `validation.poses` in the scenario" if validation else "use fewer --free-poses",
        )
    with ExitStack() as outputs:
        if truth_out is not None:
            outputs.enter_context(result_file(truth_out, inputs=[*inputs, out], force=force, option="--truth-out"))
        outputs.enter_context(result_file(out, inputs=[*inputs, *([truth_out] if truth_out else [])], force=force))
        _simulate(loaded, out, seed, true_params, truth_out, validation, free)


def free_pose_targets(scenario, names: str | None, targets_mm: str | None, true_params: Path | None):
    """The flange targets of a free-pose simulation and their true offsets [mm] (``--targets``, ``--targets-mm``).

    Offsets: ``--targets-mm``, else the ``targets`` of the ``--true-params`` JSON, else the scenario's
    declared offset; a target declared unknown without one of the first two is an error (its guess is
    not a truth).
    """
    import numpy as np

    from robotcal.cli.iso9283 import parse_targets_mm
    from robotcal.io.formats.parameters_json import read_targets


    declared = {t.name: t for t in scenario.targets if t.frame == "flange"}
    if names is None:
        # one reflector, one target: the calibration poses' "flange" target sits where [validation]'s does
        chosen: list[str] = []
        offsets: list[np.ndarray] = []
        for name, target in declared.items():
            if target.known and any(np.array_equal(target.positions, seen) for seen in offsets):
                continue
            chosen.append(name)
            if target.known:
                offsets.append(target.positions)
        if not chosen:
            raise InputError(
                f"{scenario.source}: no flange target to measure at free poses; declare [[targets]] with flange_mm "
                "(or a [validation] table)"
            )
    else:
        chosen = [name.strip() for name in names.split(",")]
        if any(not name for name in chosen) or len(set(chosen)) != len(chosen):
            raise InputError(f"--targets must be distinct target names separated by commas; got {names!r}")
        missing = [name for name in chosen if name not in declared]
        if missing:
            other = [t.name for t in scenario.targets if t.frame != "flange" and t.name in missing]
            why = f" ({', '.join(other)}: per-joint reflectors, circle points only)" if other else ""
            raise InputError(
                f"--targets {', '.join(missing)}: no such flange target in {scenario.source}{why}; declared flange "
                f"targets: {', '.join(declared) or 'none'}"
            )
    given = parse_targets_mm(targets_mm) if targets_mm is not None else {}
    unused = [name for name in given if name not in chosen]
    if unused:
        raise InputError(f"--targets-mm {', '.join(unused)}: not among the simulated targets {', '.join(chosen)}")
    from_truth = read_targets(true_params) if true_params is not None else {}
    offsets = []
    for name in chosen:
        if name in given:
            offsets.append(given[name])
        elif name in from_truth:
            offsets.append(np.asarray(from_truth[name], dtype=float))
        elif declared[name].known:
            offsets.append(np.asarray(declared[name].positions, dtype=float))
        else:
            raise InputError(
                f"target {name!r} is declared with an unknown offset (flange_mm = \"unknown\"): give the simulated "
                f"robot's true offset with --targets-mm {name}=x,y,z (its guess_mm is no truth)"
            )
    return [declared[name] for name in chosen], np.array(offsets)


def _simulate_free(loaded, seed, truth, free):
    """A capture of several flange targets at random or given free poses (``--free-poses``, ``--poses``)."""
    import numpy as np

    from robotcal import api
    from robotcal.io.formats.trajectory_csv import read_trajectory

    count, pose_file, names, targets_mm, true_params = free
    chosen, offsets = free_pose_targets(loaded, names, targets_mm, true_params)
    poses_deg = None
    if pose_file is not None:
        poses_deg = np.rad2deg(read_trajectory(pose_file, n_joints=loaded.robot.n_joints))
    capture = api.simulate_poses(
        loaded,
        poses_deg,
        n_poses=count,
        targets=chosen,
        offsets_mm={target.name: offset for target, offset in zip(chosen, offsets, strict=True)},
        true_parameters=truth,
        rng=seed,
    )
    where = f"{poses_deg.shape[0]} poses of {pose_file}" if pose_file is not None else f"{count} random poses"
    return capture, f"{capture.n_points} points: {where} x targets {', '.join(t.name for t in chosen)}", capture.seed


def _simulate(loaded, out, seed, true_params, truth_out, validation, free=None) -> None:
    from robotcal import api
    from robotcal.io.formats.capture_csv import write_capture
    from robotcal.io.formats.parameters_json import read_parameters, write_parameters
    from robotcal.io.results.provenance import versions
    from robotcal.io.schema.scenario import TruthTable

    truth = read_parameters(true_params, loaded.robot) if true_params is not None else None
    if truth_out is not None:
        truth_seed = api.seed_from(None, (loaded.truth or TruthTable()).seed)
        truth = api.perturb(loaded, rng=truth_seed)
        write_parameters(
            truth_out,
            truth,
            {
                "method": "nominal plus normal deviations of the CPA-identifiable parameters (simulation.perturb)",
                "scenario": {"name": loaded.name, "source": loaded.source},
                "truth": (loaded.truth or TruthTable()).model_dump(),
                "seed": truth_seed,
                "versions": versions(),
            },
        )
        console.print(f"wrote {truth_out}: perturbed 'true' robot (seed {truth_seed})", highlight=False, soft_wrap=True)
    if free is not None:
        capture, kind, used_seed = _simulate_free(loaded, seed, truth, (*free, true_params))
    elif validation:
        capture = api.simulate_poses(loaded, rng=seed, true_parameters=truth)
        capture, kind, used_seed = capture, f"{capture.n_points} random poses, flange target", capture.seed
    else:
        capture = api.simulate(loaded, rng=seed, true_parameters=truth)
        capture, kind, used_seed = capture, f"{capture.n_points} points in {loaded.robot.n_joints} circles", capture.seed
    write_capture(out, capture)
    console.print(
        f"wrote {out}: {kind} "
        f"(scenario {loaded.name}, instrument {loaded.instrument.name}, noise {loaded.instrument.noise}, seed {used_seed})",
        highlight=False,
        soft_wrap=True,  # one line, also where the console is 80 columns (piped): the seed stays on it
    )

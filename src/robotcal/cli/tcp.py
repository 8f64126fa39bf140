"""``robotcal tcp``: TCP position and orientation uncertainty from Monte Carlo parameter draws (ch. 5.3)."""

from __future__ import annotations

import math
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, cast

import typer

from robotcal.cli._common import Force, app_command, command_app, console
from robotcal.cli._tables import Column, FittedTable
from robotcal.errors import InputError, JointLimitWarning
from robotcal.io.results.output import check_output_folder, existing_inputs, result_folder
from robotcal.limits import BYTES_PER_POSE, SEED_BOUND, check_memory

if TYPE_CHECKING:  # numpy, the draws and the uncertainty library load in the command: a fast --help
    import numpy as np

    from robotcal.io.formats.draws_npz import ParameterDraws
    from robotcal.uncertainty.statistics import IntervalKind
    from robotcal.uncertainty.tcp import TCPUncertainty

app = command_app()

#: Display factor of each TCP coordinate: X, Y, Z in mm as they are; A, B, C from rad to deg.
_DEG = (1.0, 1.0, 1.0, *([180.0 / math.pi] * 3))


def _numbers(text: str, option: str, count: int | None = None) -> np.ndarray:
    import numpy as np

    parts = [part.strip() for part in text.replace(";", ",").split(",")]
    if any(not part for part in parts):
        raise InputError(f"{option} {text!r}: an empty field; expected comma-separated numbers")
    try:
        values = np.array([float(part) for part in parts])
    except ValueError:
        raise InputError(f"{option} {text!r}: expected comma-separated numbers") from None
    if count is not None and values.size != count:
        raise InputError(f"{option} {text!r}: expected {count} numbers; got {values.size}")
    if not np.all(np.isfinite(values)):
        raise InputError(f"{option} {text!r}: every value must be a finite number")
    return values


def _interval_kind(interval: str) -> IntervalKind:
    """``--interval`` checked: one of INTERVAL_KINDS."""
    from robotcal.uncertainty.statistics import INTERVAL_KINDS

    if interval not in INTERVAL_KINDS:
        raise InputError(f"--interval must be one of {', '.join(INTERVAL_KINDS)}; got {interval!r}")
    return cast("IntervalKind", interval)


def _draws_path(draws: Path | None, run: Path | None) -> Path:
    if (draws is None) == (run is None):
        raise InputError("give exactly one of --draws FILE and --run DIR")
    if draws is not None:
        return draws
    assert run is not None  # exactly one of the two, checked above
    for candidate in (run / "draws.npz", run / "uncertainty" / "draws.npz"):
        if candidate.is_file():
            return candidate
    raise InputError(
        f"{run}: neither {run / 'draws.npz'} nor {run / 'uncertainty' / 'draws.npz'} exists "
        "(write draws with `robotcal uncertainty --save-draws`)"
    )


def _subset(loaded: ParameterDraws, max_draws: int | None) -> np.ndarray:
    if max_draws is None or max_draws >= loaded.n_draws:
        return loaded.values
    return loaded.values[:max_draws]


def _summary_table(result: TCPUncertainty, pose: int, interval: IntervalKind) -> FittedTable:
    from robotcal.uncertainty.tcp import TCP_COORDINATES, TCP_UNITS

    low, high = result.summary.interval(interval)
    table = FittedTable(
        f"TCP at pose {pose + 1} ({result.n_draws} draws)",
        [
            Column("", "name", justify="right"),
            Column("unit", "name", justify="right"),
            Column("nominal", narrow=2),
            Column("mean"),
            Column("u (MC)"),
            Column("u (linear)", narrow=1),
            Column(f"{result.coverage:.0%} low"),
            Column("high"),
        ],
        elsewhere="tcp.csv",
    )
    for k, name in enumerate(TCP_COORDINATES):
        f = _DEG[k]
        table.add_row(
            name,
            TCP_UNITS[k],
            f"{result.nominal[pose, k] * f:.4f}",
            f"{result.summary.mean[pose, k] * f:.4f}",
            f"{result.summary.std_uncertainty[pose, k] * f:.4f}",
            f"{result.lpu_std_uncertainty[pose, k] * f:.4f}",
            f"{low[pose, k] * f:.4f}",
            f"{high[pose, k] * f:.4f}",
        )
    return table


def _readings(robot, pose: str | None, trajectory: str | None, provenance: dict) -> tuple[str, np.ndarray | None]:
    """The mode (pose, trajectory, workspace) and its readings [rad], checked against the joint limits (a
    warning naming the option or file); a trajectory's path goes into ``provenance``."""
    import numpy as np

    from robotcal.io.formats.trajectory_csv import load_trajectory
    from robotcal.uncertainty.tcp import check_readings

    if pose is not None:
        readings = _numbers(pose, "--pose")
        if readings.size != robot.n_joints:
            raise InputError(
                f"--pose {pose!r}: {readings.size} joint readings but robot {robot.name!r} has {robot.n_joints} joints"
            )
        return "pose", check_readings(robot, np.deg2rad(readings)[None], name="--pose")
    if trajectory is not None:
        readings, path = load_trajectory(trajectory, n_joints=robot.n_joints)
        provenance["trajectory"] = path
        return "trajectory", check_readings(robot, readings, name="trajectory", source=path)
    return "workspace", None


def _print_summary(result, ws, mode: str, interval: IntervalKind) -> None:
    """The console summary of ``robotcal tcp``: the pose's table and ellipsoid, or the range of the position
    uncertainty over the poses (and the workspace percentiles)."""
    import numpy as np

    if mode == "pose":
        console.print(_summary_table(result, 0, interval))
        semi = ", ".join(f"{a:.4f}" for a in result.ellipsoid.semi_axes[0])
        console.print(
            f"{result.coverage:.0%} position ellipsoid: semi-axes {semi} mm, "
            f"{result.ellipsoid.fraction_inside[0]:.2%} of the draws inside",
            highlight=False,
        )
    else:
        worst = int(np.argmax(result.position_uncertainty))
        best = int(np.argmin(result.position_uncertainty))
        console.print(
            f"{result.n_poses} poses: position uncertainty sqrt(uX^2+uY^2+uZ^2) from "
            f"{result.position_uncertainty[best]:.4f} mm (pose {best + 1}) to "
            f"{result.position_uncertainty[worst]:.4f} mm (pose {worst + 1}); largest range "
            f"{(result.value_range[:, :3]).max():.4f} mm",
            highlight=False,
        )
        if ws is not None:
            marks = ", ".join(
                f"P{level:g} {value:.4f}"
                for level, value in zip(ws.percentiles, ws.position_uncertainty_percentiles, strict=True)
            )
            console.print(f"percentiles of the position uncertainty [mm]: {marks}", highlight=False)
    console.print(
        "orientation: KUKA A (about Z), B (about Y), C (about X); thesis Table 5.8 lists them as C, B, A",
        highlight=False,
    )


@app_command(app)
def tcp(
    out: Annotated[Path, typer.Option("--out", "-o", help="Result folder to write (tcp.csv, tcp.json, figures).")],
    draws: Annotated[
        Path | None, typer.Option("--draws", help="draws.npz of `robotcal uncertainty --save-draws`.")
    ] = None,
    run: Annotated[
        Path | None, typer.Option("--run", help="Uncertainty folder (DIR/draws.npz) or run folder (DIR/uncertainty/).")
    ] = None,
    pose: Annotated[str | None, typer.Option("--pose", help='Joint readings in deg, "q1,...,qN".')] = None,
    trajectory: Annotated[
        str | None, typer.Option("--trajectory", help="Pose CSV (q1..qN in deg) or built-in name (kr5-sweep-75).")
    ] = None,
    workspace: Annotated[
        int | None, typer.Option("--workspace", min=1, help="Number of random poses within the joint limits.")
    ] = None,
    tool: Annotated[str | None, typer.Option("--tool", help='TCP offset on the flange "x,y,z" [mm].')] = None,
    coverage: Annotated[float, typer.Option("--coverage", help="Coverage probability.")] = 0.95,
    interval: Annotated[str, typer.Option("--interval", help="Coverage interval: symmetric | shortest.")] = "symmetric",
    seed: Annotated[
        int, typer.Option("--seed", min=0, max=SEED_BOUND - 1, help="Seed of the --workspace pose sample.")
    ] = 0,
    max_draws: Annotated[
        int | None, typer.Option("--max-draws", min=2, help="Use only the first N draws (quicker maps).")
    ] = None,
    force: Force = False,
) -> None:
    """TCP position (X, Y, Z) and KUKA orientation (A, B, C) uncertainty at a pose, along a trajectory, or over the workspace."""
    import numpy as np

    from robotcal import api
    from robotcal.io.formats.draws_npz import read_draws
    from robotcal.io.results.provenance import versions
    from robotcal.io.results.tcp_results import write_tcp_folder

    started = time.perf_counter()
    if sum(option is not None for option in (pose, trajectory, workspace)) != 1:
        raise InputError("give exactly one of --pose, --trajectory and --workspace")
    kind = _interval_kind(interval)
    if workspace is not None:
        check_memory(
            f"--workspace {workspace}",
            workspace * float(BYTES_PER_POSE),
            "ask for fewer workspace poses (a map of 10^3-10^4 poses is usually enough)",
        )
    inputs = existing_inputs(draws, run, trajectory)
    check_output_folder(out, inputs=inputs, force=force)
    source = _draws_path(draws, run)
    inputs += existing_inputs(source)
    loaded = read_draws(source)
    robot = loaded.robot
    values = _subset(loaded, max_draws)
    tool_mm = None if tool is None else _numbers(tool, "--tool", 3)
    provenance = {
        "draws_file": str(source),
        "draws_seed": loaded.seed,
        "draws_in_file": loaded.n_draws,
        "versions": versions(),
    }
    mode, readings = _readings(robot, pose, trajectory, provenance)
    ws = None
    if readings is None:  # the workspace mode: exactly one of --pose, --trajectory and --workspace is given
        assert workspace is not None
        ws = api.workspace_uncertainty(robot, values, workspace, tool_mm=tool_mm, coverage=coverage, rng=seed)
        result = ws.tcp
    else:
        with warnings.catch_warnings():  # the readings were checked above, naming the option or file
            warnings.simplefilter("ignore", JointLimitWarning)
            result = api.tcp_uncertainty(
                robot, values, np.rad2deg(readings), tool_mm=tool_mm, coverage=coverage, keep_draws=mode == "pose"
            )
    provenance["mode"] = mode
    provenance["seconds"] = round(time.perf_counter() - started, 3)
    with result_folder(out, inputs=inputs, force=force, command="robotcal tcp") as folder:
        write_tcp_folder(folder, result, interval=kind, workspace=ws, provenance=provenance)
        from robotcal.plots.tcp import write_tcp_figures

        write_tcp_figures(result, folder, mode, workspace=ws)

    _print_summary(result, ws, mode, kind)
    console.print(f"wrote {out} in {time.perf_counter() - started:.1f} s ({result.n_draws} draws)", highlight=False)

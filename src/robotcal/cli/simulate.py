"""``robotcal simulate SCENARIO --out CAPTURE.csv``: a synthetic Circle Point (or validation) capture."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Annotated

import typer

from robotcal import api
from robotcal.cli._common import (
    BYTES_PER_POSE,
    FORCE_HELP,
    SEED_BOUND,
    check_memory,
    command_app,
    console,
    handle_errors,
)
from robotcal.errors import InputError
from robotcal.io import load_scenario, read_parameters, write_capture, write_parameters
from robotcal.io.output import existing_inputs, result_file
from robotcal.io.provenance import versions
from robotcal.io.scenario import TruthTable, ValidationTable

app = command_app()


@app.command()
@handle_errors
def simulate(
    scenario: Annotated[str, typer.Argument(help="Built-in scenario name or scenario TOML path.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Capture CSV to write.")],
    seed: Annotated[
        int | None,
        typer.Option(
            min=0,
            max=SEED_BOUND - 1,
            help="Seed of the random draws (default: the scenario's capture.seed, or validation.seed).",
        ),
    ] = None,
    true_params: Annotated[
        Path | None, typer.Option("--true-params", help="Parameter JSON of the 'real' robot (default: nominal).")
    ] = None,
    truth_out: Annotated[
        Path | None,
        typer.Option(
            "--truth-out",
            help="Perturb the nominal robot per the scenario's [truth] table, simulate that robot and write it here.",
        ),
    ] = None,
    validation: Annotated[
        bool,
        typer.Option(
            "--validation", help="Simulate a validation capture at random poses ([validation] table) instead."
        ),
    ] = False,
    force: Annotated[bool, typer.Option("--force", help=FORCE_HELP)] = False,
) -> None:
    """Simulate the scenario's capture and write it as a capture CSV."""
    loaded = load_scenario(scenario)
    if true_params is not None and truth_out is not None:
        raise InputError("give either --true-params (an existing truth) or --truth-out (a new perturbed truth)")
    inputs = existing_inputs(scenario, *loaded.files, true_params)
    if validation:
        poses = (loaded.validation or ValidationTable()).poses
        check_memory(
            f"a validation capture of {poses:,} poses",
            poses * float(BYTES_PER_POSE),
            "lower `validation.poses` in the scenario",
        )
    with ExitStack() as outputs:
        if truth_out is not None:
            outputs.enter_context(result_file(truth_out, inputs=[*inputs, out], force=force, option="--truth-out"))
        outputs.enter_context(result_file(out, inputs=[*inputs, *([truth_out] if truth_out else [])], force=force))
        _simulate(loaded, out, seed, true_params, truth_out, validation)


def _simulate(loaded, out, seed, true_params, truth_out, validation) -> None:
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
        console.print(f"wrote {truth_out}: perturbed 'true' robot (seed {truth_seed})", highlight=False)
    if validation:
        capture = api.simulate_validation(loaded, rng=seed, true_parameters=truth)
        kind = f"{capture.n_points} random poses, flange target"
    else:
        capture = api.simulate(loaded, rng=seed, true_parameters=truth)
        kind = f"{capture.n_points} points in {loaded.robot.n_joints} circles"
    write_capture(out, capture)
    console.print(
        f"wrote {out}: {kind} "
        f"(scenario {loaded.name}, instrument {loaded.instrument.name}, noise {loaded.instrument.noise}, "
        f"seed {capture.seed})",
        highlight=False,
    )

"""``robotcal evaluate --scenario S --params P1.json [P2.json ...] --capture VALIDATION.csv --out DIR``."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Annotated

import typer

from robotcal.cli._common import Force, check_memory, command_app, console, handle_errors, pairs_bytes
from robotcal.cli._tables import Column, FittedTable
from robotcal.errors import InputError
from robotcal.io.results.output import check_output_folder, existing_inputs, result_folder

app = command_app()


def _label(path: Path, used: set[str]) -> str:
    label = path.stem
    while label in used:
        label = f"{path.parent.name}/{label}" if "/" not in label else label + "'"
    used.add(label)
    return label


def _borrow_offsets(scenario, set_targets: dict, labels, files: dict, captures: dict) -> dict[str, str]:
    """Give the sets without estimated offsets (the nominal set, a JSON without ``targets``) those of the
    first ``--params`` file that carries them (``set_targets`` is modified in place); returns a note per set that
    evaluates points of ``captures`` with offsets it did not estimate: borrowed ones, and the unknown targets that
    no set lent it, left at their ``guess_mm`` (the library warns for those: :class:`GuessedOffsetWarning`).
    """
    from robotcal import api
    from robotcal.identification.evaluation import guessed_targets

    unknown = {t.name for t in scenario.targets if t.frame == "flange" and not t.known}
    if not unknown:
        return {}
    used = {  # the unknown targets that points lie on
        name for capture in captures.values() for name in guessed_targets(capture, api.capture_targets(scenario, capture), {})
    }
    unknown |= used  # a re-seated target's offsets: one per session, NAME@SESSION
    carriers = [label for label in labels if unknown & set(set_targets.get(label) or {})]
    notes = {}
    for label in labels:
        parts, owner = [], label
        if label not in carriers and carriers:
            owner = carriers[0]
            set_targets[label] = {name: set_targets[owner][name] for name in unknown & set(set_targets[owner])}
            which = f"the first of {len(carriers)} that carry them" if len(carriers) > 1 else "the only one that does"
            if used & set(set_targets[label]):
                parts.append(f"unknown target offsets estimated by {owner} ({files[owner]}; {which})")
        guessed = sorted(used - set(set_targets.get(label) or {}))
        if guessed:
            one = len(guessed) == 1
            who = f"{owner} did not estimate {'it' if one else 'them'}" if carriers else "no parameter file estimates them"
            parts.append(f"{', '.join(guessed)} at {'its' if one else 'their'} guess (guess_mm): {who}")
        if parts:
            notes[label] = "; ".join(parts)
    return notes


def _absolute_bases(scenario, provenances: dict, sessions: dict) -> tuple[dict, dict]:
    """Base frame of each parameter set for the absolute view, and a note per set saying where it comes from.

    ``provenances``: set name -> the parameter JSON's ``provenance`` (empty for the nominal set). The base
    frame a fit recorded (``provenance.tracker_from_base``: a refinement's estimated or held one, CPA's given
    or registered one) is used as it is, and a refinement over sessions gives each session's frame (``sessions``: set
    name -> session name -> frame, from the JSON's ``sessions``); a set without one (the nominal set, a distances-criterion refinement)
    is evaluated in the scenario's ``tracker_from_base``; without one it is left out of the absolute view (a note
    says so), and no set with a base frame at all is an error.
    """
    import numpy as np

    bases: dict[str, np.ndarray | None] = {}
    notes: dict[str, str] = {}
    for name, provenance in provenances.items():
        recorded = (provenance or {}).get("tracker_from_base")
        if sessions.get(name):  # a refinement over sessions: each session's frame
            bases[name] = sessions[name]
            notes[name] = (
                f"the base frames of sessions {', '.join(sessions[name])} recorded in its parameter JSON (sessions); "
                "a capture of another session is evaluated in the first"
            )
            continue
        if recorded is not None:
            bases[name] = np.asarray(recorded, dtype=float)
            notes[name] = "the base frame recorded in its parameter JSON (provenance.tracker_from_base)"
            continue
        why = (
            "the distances criterion has no base frame"
            if (provenance or {}).get("criterion") == "distances"
            else "no base frame recorded"
        )
        if not scenario.gives_tracker_from_base:  # left out of the absolute view, said (issue 29)
            bases[name] = None
            notes[name] = (
                f"left out: {why}, and {scenario.source} gives no `tracker_from_base` (the points and distances views "
                "still compare it)"
            )
            continue
        bases[name] = np.asarray(scenario.tracker_from_base, dtype=float)
        notes[name] = f"{why}: the scenario's tracker_from_base is used"
    if all(base is None for base in bases.values()):
        raise InputError(
            f"--absolute: no parameter set recorded a base frame and {scenario.source} gives no `tracker_from_base`: "
            "the absolute error cannot be computed; give the scenario's tracker_from_base or a set that recorded one"
        )
    return bases, notes


def _convergence(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    entry = (data.get("provenance") or {}).get("convergence") if isinstance(data, dict) else None
    if isinstance(entry, dict) and "rms_mm" in entry and "criterion" in entry:
        return entry
    return None


def _parameter_sets(params: list[Path], robot, nominal: bool) -> tuple[dict, dict, dict, dict, dict, dict]:
    """The named sets of ``--params`` (after the nominal one), with each file's provenance, flange targets, path,
    convergence history (of the sets that record one) and session frames."""
    from robotcal.io.formats.parameters_json import read_parameters, read_sessions, read_targets
    from robotcal.kinematics.model import ParameterSet

    used: set[str] = set()
    sets: dict[str, ParameterSet] = {}
    if nominal:
        sets["nominal"] = ParameterSet.nominal(robot)
        used.add("nominal")
    histories = {}
    provenances: dict = {"nominal": {}} if nominal else {}
    set_targets: dict = {}
    sessions: dict = {}
    files: dict[str, Path] = {}
    for path in params:
        label = _label(path, used)
        files[label] = path
        sets[label] = read_parameters(path, robot)
        provenances[label] = (json.loads(path.read_text(encoding="utf-8")) or {}).get("provenance") or {}
        set_targets[label] = read_targets(path)
        sessions[label] = read_sessions(path)
        history = _convergence(path)
        if history is not None:
            histories[label] = history
    return sets, provenances, set_targets, files, histories, sessions


def _print_tables(rows, captures: dict, views: tuple[str, ...]) -> None:
    """One table per capture and view: mean, max, RMS and improvement of every set."""
    for capture_name in captures:
        for view in views:
            headers = ("mean [mm]", "max [mm]", "RMS [mm]", "improvement [%]")
            table = FittedTable(
                f"{capture_name}: {view} view",
                [Column("parameter set", "name"), *(Column(header) for header in headers)],
            )
            for row in rows:
                if row.capture == capture_name and row.view == view:
                    table.add_row(
                        row.parameter_set,
                        f"{row.mean_error_mm:.4f}",
                        f"{row.max_error_mm:.4f}",
                        f"{row.rms_error_mm:.4f}",
                        f"{row.improvement_pct:.2f}",
                    )
            console.print(table)


_MOVED_KEYS = ("capture", "parameter_set", "rms_error_mm")
_TURNED_KEYS = ("parameter_set", "view", "capture", "n_errors", "mean_error_deg", "max_error_deg", "rms_error_deg")


def _issue29_parts(document, rows, captures, sets, scenario, files, views, bases, set_targets) -> tuple[list, tuple]:
    """Sessions and 6-DoF probes (issue 29): the absolute rows of a capture from another station
    (``station_moved``) and the orientation errors of the sets that estimated a probe's rotation on the captures
    with orientations (``orientation``), both added to ``document`` when there are any."""
    from robotcal import api
    from robotcal.identification.evaluation import evaluate_orientation
    from robotcal.io.formats.parameters_json import read_probe

    moved = [row for row in rows if row.station]
    if moved:
        document["station_moved"] = [{key: getattr(row, key) for key in _MOVED_KEYS} for row in moved]
    turned: tuple = ()
    if any(c.orientation is not None for c in captures.values()):
        probes = {label: rotation for label, path in files.items() if (rotation := read_probe(path)) is not None}
        reflectors = {name: api.capture_targets(scenario, c) for name, c in captures.items()}
        turned = evaluate_orientation(
            captures, sets, reflectors, probes, views=[v for v in views if v != "distances"], bases=bases,
            set_targets=set_targets,
        )  # fmt: skip
    if turned:
        document["orientation"] = [{key: getattr(row, key) for key in _TURNED_KEYS} for row in turned]
    return moved, turned


def _print_orientation(turned) -> None:
    """One table of the orientation errors [deg] of the sets with a probe rotation, per capture and view."""
    for capture_name, view in dict.fromkeys((row.capture, row.view) for row in turned):
        table = FittedTable(
            f"{capture_name}: orientation, {view} view",
            [Column("parameter set", "name"), *(Column(h) for h in ("mean [deg]", "max [deg]", "RMS [deg]"))],
        )
        for row in turned:
            if (row.capture, row.view) == (capture_name, view):
                table.add_row(
                    row.parameter_set, f"{row.mean_error_deg:.5f}", f"{row.max_error_deg:.5f}", f"{row.rms_error_deg:.5f}"
                )
        console.print(table)


def _print_moved(moved) -> None:
    """One line per absolute row of a capture measured from another station than the set's base frame."""
    for row in moved:
        console.print(
            f"absolute view, {row.parameter_set} on {row.capture}: FLAGGED, measured from another tracker station "
            f"than the recorded base frame (absolute RMS {row.rms_error_mm:.4g} mm, far above the registered one): "
            "these absolute errors measure the station, not the parameters; read the points view",
            highlight=False,
            markup=False,
        )


@app.command()
@handle_errors
def evaluate(
    scenario: Annotated[str, typer.Option("--scenario", "-s", help="Scenario name or TOML: robot and targets.")],
    params: Annotated[list[Path], typer.Option("--params", "-p", help="Parameter JSON to evaluate (repeatable).")],
    capture: Annotated[list[Path], typer.Option("--capture", "-c", help="Capture CSV to evaluate on (repeatable).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Result folder to write.")],
    nominal: Annotated[
        bool, typer.Option("--nominal/--no-nominal", help="Include the nominal parameters first, as the reference.")
    ] = True,
    force: Force = False,
    absolute: Annotated[
        bool,
        typer.Option(
            "--absolute",
            help="Add the absolute view: |T p - m| with each set's own base frame (the one its parameter JSON "
            "records, else the scenario's tracker_from_base), no re-registration.",
        ),
    ] = False,
) -> None:
    """Mean/max errors of parameter sets under the points and distances views (thesis Tables 4.10/4.11)."""
    from robotcal import api
    from robotcal.identification.evaluation import StationMovedWarning
    from robotcal.io.formats.capture_csv import read_capture
    from robotcal.io.results.evaluation_files import convergence_of, evaluation_document, write_evaluation_folder
    from robotcal.io.schema.scenario import load_scenario

    inputs = existing_inputs(scenario, *params, *capture)
    check_output_folder(out, inputs=inputs, force=force)
    loaded = load_scenario(scenario)
    inputs += existing_inputs(*loaded.files)
    robot = loaded.robot
    sets, provenances, set_targets, files, histories, sessions = _parameter_sets(params, robot, nominal)
    if not sets:
        raise InputError("nothing to evaluate: give --params or keep --nominal")
    captures = {}
    capture_labels: set[str] = set()
    for path in capture:
        captures[_label(path, capture_labels)] = read_capture(path, n_joints=robot.n_joints)
    largest = max((c.n_points for c in captures.values()), default=0)
    check_memory(
        f"the distances view of a capture of {largest} points",
        pairs_bytes(largest),
        "evaluate on a capture with fewer points",
    )
    target_notes = _borrow_offsets(loaded, set_targets, list(sets), files, captures)
    views = ("points", "distances", "absolute") if absolute else ("points", "distances")
    bases, base_notes = _absolute_bases(loaded, provenances, sessions) if absolute else (None, {})
    with warnings.catch_warnings():  # said below, row by row, with the absolute RMS
        warnings.simplefilter("ignore", StationMovedWarning)
        rows = api.evaluate(captures, sets, loaded, views=views, bases=bases, set_targets=set_targets)
    document = evaluation_document(
        rows,
        loaded,
        parameter_files={label: str(path) for label, path in zip(list(sets)[int(nominal) :], params, strict=True)},
        capture_files={label: str(path) for label, path in zip(captures, capture, strict=True)},
        reference=next(iter(sets)),
        histories=histories,
    )
    if absolute:
        document["settings"]["views"]["absolute"] = (
            "distance per point |T p - m| with the set's own base frame, no re-registration"
        )
        document["settings"]["absolute_base_frames"] = base_notes
    if target_notes:
        document["settings"]["target_offsets"] = target_notes
    moved, turned = _issue29_parts(document, rows, captures, sets, loaded, files, views, bases, set_targets)
    with result_folder(out, inputs=inputs, force=force, command="robotcal evaluate") as folder:
        write_evaluation_folder(folder, rows, document)
        if histories:
            from robotcal.plots.refine import plot_convergence

            plot_convergence(convergence_of(document), folder / "convergence.png")
    _print_tables(rows, captures, views)
    for label, note in base_notes.items():
        console.print(f"absolute view, {label}: {note}", highlight=False, markup=False)
    for label, note in target_notes.items():
        console.print(f"{label}: {note}", highlight=False, markup=False)
    _print_moved(moved)
    _print_orientation(turned)
    console.print(
        f"wrote {out}/evaluation.csv, evaluation.json" + (", convergence.png" if histories else ""), highlight=False
    )

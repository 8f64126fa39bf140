"""The summary section: facts of the run, the headline cards (how good, how sure, where), the stage table."""

from __future__ import annotations

import re

from robotcal.io.results.run_folder import OUTPUTS
from robotcal.io.results.run_summary import set_label
from robotcal.report.page import _angle, _fmt, _length, _micrometres, _number, _Page


def _card(question: str, label: str, value: str, detail: str = "", caution: str = "") -> dict:
    """A headline card; ``caution``: a short warning shown above the detail (e.g. a pose outside the limits)."""
    return {
        "question": question,
        "label": label,
        "value": value,
        "detail": detail,
        "caution": caution,
        "na": value == "n/a",
    }


#: One reading outside a joint's limits, as ``robotcal.uncertainty.tcp.check_readings`` words it in the
#: joint-limit warning the TCP stage records in run.json ("pose 1: J2 = -80 deg outside [-45, 190] deg").
_OUTSIDE = re.compile(r"pose \d+: J(\d+) = \S+ deg outside \[(\S+), (\S+)\] deg")


def _tcp_pose(page: _Page) -> tuple[str, str, list[str]]:
    """The pose of the TCP headline: where it comes from (``"the thesis's Table 5.8 pose"``), its readings
    (``"-60, -80, 45, -200, 125, -280"`` [deg], empty if unknown) and the joints whose limits they are outside
    (``["J2", "J4", "J5"]``).

    The readings are ``tcp/pose/tcp.json``'s first pose; the limits those of the joints that the run's
    joint-limit warnings name (a reading outside its limits always gets one). The warnings do not say which
    TCP mode they are about (a trajectory's poses are numbered from 1 too), so each reading of this pose is
    compared with its joint's limits here.
    """
    document = page.json("tcp/pose/tcp.json") or {}
    provenance = found if isinstance(found := document.get("provenance"), dict) else {}
    source = found if isinstance(found := provenance.get("pose"), str) else ""
    if source.startswith("thesis Table 5.8 pose"):
        where = "the thesis's Table 5.8 pose"
    elif source.startswith("tcp.pose_deg"):
        where = "the scenario's tcp.pose_deg"
    else:
        where = "the first pose"
    poses = document.get("poses")
    first = poses[0] if isinstance(poses, list) and poses and isinstance(poses[0], dict) else {}
    readings = first.get("readings_deg")
    readings = [_number(v) for v in readings] if isinstance(readings, list) else []
    if not readings or None in readings:
        return where, "", []
    limits: dict[int, tuple[float, float]] = {}
    for note in page.summary.notes:
        if "outside the joint limits" in note:
            for joint, low, high in _OUTSIDE.findall(note):
                lower, upper = _number(low), _number(high)
                if lower is not None and upper is not None:
                    limits[int(joint)] = lower, upper
    outside = []
    for joint, (low, high) in sorted(limits.items()):
        if joint <= len(readings):
            value = readings[joint - 1]
            slack = 1e-6 * max(1.0, abs(value))  # the warning prints the limits with %g
            if not low - slack <= value <= high + slack:
                outside.append(f"J{joint}")
    return where, ", ".join(_fmt(v, ".6g", exponent=False) for v in readings), outside


def _facts_of_run(page: _Page) -> list[dict]:
    """Robot, scenario, instrument, captures, seed, method: ``[{"label", "text", "code"}]``."""
    record = page.record
    scenario = found if isinstance(found := record.get("scenario"), dict) else {}
    facts = []
    if isinstance(record.get("robot"), str):
        facts.append({"label": "robot", "text": record["robot"], "code": None})
    if isinstance(scenario.get("name"), str):
        description = scenario.get("description")
        text = scenario["name"] + (f" — {description}" if isinstance(description, str) and description else "")
        facts.append({"label": "scenario", "text": text, "code": None})
    instrument = found if isinstance(found := scenario.get("instrument"), dict) else {}
    if isinstance(instrument.get("name"), str):
        a_um, b_um = _number(instrument.get("a_um")), _number(instrument.get("b_um_per_m"))
        text = instrument["name"]
        if a_um is not None and b_um is not None:
            text += f", U(L) = {_fmt(a_um)} µm + {_fmt(b_um)} µm/m · L"
        facts.append({"label": "instrument", "text": text, "code": None})
    for name, what in (
        ("capture.csv", "calibration capture"),
        ("poses.csv", "calibration poses"),
        ("validation.csv", "validation points"),
    ):
        table = page.table(name)
        if table is not None:
            text = f"{len(table.rows)} points"
            if name == "capture.csv" and "circle" in table.header:
                text += f" in {len(set(table.column('circle')))} circles"
            facts.append({"label": what, "text": text, "code": name})
    if record.get("seed") is not None:
        facts.append({"label": "seed", "text": str(record["seed"]), "code": None})
    provenance = (page.json("cpa/parameters.json") or {}).get("provenance")
    if isinstance(provenance, dict) and isinstance(provenance.get("method"), str):
        facts.append({"label": "identification", "text": provenance["method"], "code": None})
    return facts


def _absolute(base_frame: str | None) -> str:
    """How ``tcp/consistency.json`` placed the predictions: with the base frame given (no registration), or a
    best-fit registration of them onto the measurements."""
    if base_frame == "registered":
        return "after a best-fit registration of the base frame"
    return f"with the base frame {base_frame or 'given'}, no registration"


def _validation_detail(page: _Page) -> str:
    """What the numbers of the validation card are: means of the evaluation's errors in its view (the points
    view: distances after a best-fit registration of each model's predicted points onto the measured ones), the
    RMS of the same errors, and the consistency check's absolute errors of the deployed model, which differ."""
    summary = page.summary
    before, after = summary.validation_before_set or "before", summary.validation_after_set or "after"
    capture, view = summary.validation_capture or "validation", summary.validation_view or "points"
    rows = {}
    for row in (page.json("evaluation/evaluation.json") or {}).get("rows") or []:
        if isinstance(row, dict) and row.get("capture") == capture and row.get("view") == view:
            rows[row.get("parameter_set")] = row
    count = _number((rows.get(after) or {}).get("n_errors"))
    points = f"the {int(count)} {capture} points" if count is not None else f"the {capture} points"
    if view == "points":
        what = (
            f"mean distance |predicted − measured| at {points} after a best-fit registration of each model's "
            "predictions (evaluation, points view)"
        )
    else:
        what = f"mean error at {points} (evaluation, {view} view)"
    text = f"{what}; {before} → {after}" + (f" ({set_label(after)})" if set_label(after) != after else "")
    rms = [_number((rows.get(name) or {}).get("rms_error_mm")) for name in (before, after)]
    if None not in rms:
        text += f"; RMS {_length(rms[0])} → {_length(rms[1])}"
    check = summary.consistency
    if check is not None and view == "points" and check.base_frame != "registered":
        absolute = _number((page.json("tcp/consistency.json") or {}).get("observed_mean_mm"))
        mean = f"mean {_length(absolute)}, " if absolute is not None else ""
        text += (
            f"; deployed model {_absolute(check.base_frame)} (validation consistency): "
            f"{mean}RMS {_length(check.observed_rms_mm)}"
        )
    return text


def _uncertainty_cards(summary) -> list[dict]:
    """The largest standard uncertainties of the lengths and of the angles (the deployed model's Monte Carlo)."""
    cards = []
    refined, cpa = summary.uncertainty("uncertainty-refined"), summary.uncertainty("uncertainty")
    shown = refined or cpa
    model = "refined model (deployed)" if refined is not None else "CPA model"
    for label, unit, value_of, name_of, fmt in (
        ("largest standard uncertainty, lengths", "mm", "length_mm", "length_name", _length),
        ("largest standard uncertainty, angles", "deg", "angle_deg", "angle_name", _angle),
    ):
        value = getattr(shown, value_of) if shown is not None else None
        if value is None:
            cards.append(_card("How sure are we?", label, "n/a", "uncertainty stage not run"))
            continue
        name, over = getattr(shown, name_of), ""
        if refined is not None:
            over = ", largest over the parameters the refinement determines"
            if unit in shown.set_aside:
                u, aside_name, why = shown.set_aside[unit]
                over += f"; larger: {aside_name}, {fmt(u)}, {why}"
        detail = f"{name}, {model}, Monte Carlo (GUM-S1){over}"
        if refined is not None and cpa is not None and getattr(cpa, value_of) is not None:
            detail += f"; CPA alone: {fmt(getattr(cpa, value_of))} ({getattr(cpa, name_of)})"
        if unit in shown.bias:  # the bias beside the u, never hidden by it
            bias, bias_name, ratio = shown.bias[unit]
            treated = f", {shown.bias_treatment}" if shown.bias_treatment else ""
            detail += f"; largest bias {fmt(bias)} ({bias_name}, {abs(ratio):.1f} u){treated}"
        cards.append(_card("How sure are we?", label, fmt(value), detail))
    return cards


def _tcp_pose_card(page: _Page) -> dict:
    """The TCP position uncertainty at the pose."""
    pose = page.summary.tcp_pose
    if pose is not None:
        where, readings, outside = _tcp_pose(page)
        detail = f"√(u_X² + u_Y² + u_Z²) at {where}"
        caution = ""
        if outside:  # the thesis's Table 5.8 pose is: say so where the number is read
            detail += f", outside the joint limits of {', '.join(outside)}"
            caution = f"pose outside the joint limits of {', '.join(outside)}"
        detail += f" (readings {readings} deg)" if readings else ""
        detail += f" (first of {pose.poses} poses)" if pose.poses > 1 else ""
        detail += f"; {pose.model}" if pose.model else ""
        if pose.ellipsoid_mm is not None:
            share = f"{_fmt(pose.coverage * 100, '.3g')} % " if pose.coverage else ""
            detail += f"; largest semi-axis of the {share}ellipsoid {_length(pose.ellipsoid_mm)}"
        return _card("How sure are we?", "TCP position uncertainty at the pose", _length(pose.first_mm), detail, caution)
    return _card("How sure are we?", "TCP position uncertainty at the pose", "n/a", "tcp pose not run")


def _cards(page: _Page) -> list[dict]:
    summary = page.summary
    cards = []
    if summary.validation_before_mm is not None and summary.validation_after_mm is not None:
        cards.append(
            _card(
                "How good is it?",
                "mean validation error, before → after",
                f"{_length(summary.validation_before_mm)} → {_length(summary.validation_after_mm)}",
                _validation_detail(page),
            )
        )
    else:
        why = "evaluation stage not run" if not page.has("evaluation") else "no headline in evaluation.json"
        cards.append(_card("How good is it?", "mean validation error, before → after", "n/a", why))
    if summary.circle_rms_mm is not None:
        circle = f"circle J{summary.circle_rms_circle}; " if summary.circle_rms_circle is not None else ""
        cards.append(
            _card(
                "How good is it?",
                "largest circle-fit RMS",
                f"{_fmt(summary.circle_rms_mm * 1e3, '.2f')} µm",
                f"{circle}{summary.circles} circles fitted by CPA",
            )
        )
    cards += _uncertainty_cards(summary)
    cards.append(_tcp_pose_card(page))
    workspace = summary.tcp_workspace
    if workspace is not None:
        cards.append(
            _card(
                "Where can I trust it?",
                "TCP position uncertainty over the workspace",
                f"{_length(workspace.median_mm)} / {_length(workspace.p95_mm)}",
                f"median / 95th percentile of {workspace.poses} poses; worst {_length(workspace.max_mm)}"
                + (f"; {workspace.model}" if workspace.model else ""),
            )
        )
    else:
        cards.append(
            _card("Where can I trust it?", "TCP uncertainty over the workspace", "n/a", "workspace map not run")
        )
    trajectory = summary.tcp_trajectory
    if trajectory is not None:
        cards.append(
            _card(
                "Where can I trust it?",
                "TCP uncertainty along the trajectory",
                f"≤ {_length(trajectory.max_mm)}",
                f"largest of {trajectory.poses} poses; smallest {_length(trajectory.min_mm)}"
                + (f"; {trajectory.model}" if trajectory.model else ""),
            )
        )
    check = summary.consistency
    if check is not None:
        registered = check.base_frame == "registered"
        cards.append(
            _card(
                "Does the uncertainty explain the error?",
                "validation RMS error, expected → observed",
                f"{_length(check.expected_rms_mm)} → {_length(check.observed_rms_mm)}",
                f"expected = √(predicted² + instrument²) = √({_length(check.predicted_rms_mm)}² + "
                f"{_length(check.instrument_rms_mm)}²) at {check.poses} validation poses ({check.model}"
                + (", base frame registered: the registration absorbs part of the error" if registered else "")
                + f"); observed: RMS of the errors {_absolute(check.base_frame)}"
                + ("" if registered else " (the validation card's errors are after a best-fit registration)")
                + f"; observed / expected = {_fmt(check.ratio, '.3g')}: {check.verdict}",
            )
        )
    return cards


def _summary(page: _Page) -> dict:
    stages = found if isinstance(found := page.record.get("stages"), dict) else {}
    rows = []
    for stage, outputs in OUTPUTS.items():
        if stage == "report":
            continue
        entry = found if isinstance(found := stages.get(stage), dict) else {}
        present = any(page.has(name) for name in outputs)
        status = found if isinstance(found := entry.get("status"), str) else None
        shown = status or ("done" if present else "not run")
        css = "failed" if shown in ("failed", "error") else ("ok" if present else "missing")
        detail = _micrometres(entry["detail"]) if isinstance(entry.get("detail"), str) else ""
        seconds = _fmt(_number(entry.get("seconds")), ".2f")
        rows.append(
            {"stage": stage, "outputs": outputs, "status": shown, "css": css, "seconds": seconds, "detail": detail}
        )
    return {
        "present": True,
        "facts": _facts_of_run(page),
        "cards": _cards(page),
        "stages": rows,
        "notes": page.summary.notes,
    }

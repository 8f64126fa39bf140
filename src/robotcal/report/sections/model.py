"""The model-choice section (issue 22): calibration and cross-validation error of every model fitted, the chosen
one and why, its joint-model parameters with their u, the validation error with and without the joint model, and
the consistency check of the deployed model."""

from __future__ import annotations

from robotcal.report.page import _block, _fmt, _length, _number, _Page, _Table


def _candidates(provenance: dict) -> tuple[list[dict], str, str]:
    """The cross-validated models, the chosen one and the reason, from a refinement's provenance."""
    choice = found if isinstance(found := provenance.get("model_choice"), dict) else None
    if choice is not None:
        listed = [c for c in choice.get("candidates") or [] if isinstance(c, dict)]
        return listed, str(choice.get("chosen", "")), str(choice.get("reason", ""))
    single = provenance.get("cross_validation")
    model = str(provenance.get("model", "geometric"))
    return ([single] if isinstance(single, dict) else []), model, ""


def _observed(base_frame: str | None) -> str:
    """What the consistency check's observed RMS is: with the given base frame (absolute), or registered."""
    if base_frame == "registered":
        return "RMS, after a best-fit registration of the base frame"
    return f"RMS, base frame {base_frame or 'given'}, no registration"


def _candidates_table(candidates: list[dict], chosen: str, reason: str) -> list:
    """The cross-validation table of the models fitted, the chosen one tagged."""
    blocks: list = []
    if candidates:
        folds = candidates[0].get("folds")
        rows, dim = [], set()
        for k, c in enumerate(candidates):
            fold_rms = [v for v in (_number(x) for x in c.get("fold_rms_mm") or []) if v is not None]
            spread = f"{_fmt(min(fold_rms) * 1e3, '.3g')} … {_fmt(max(fold_rms) * 1e3, '.3g')}" if fold_rms else ""
            rows.append(
                [
                    str(c.get("model", "")),
                    _fmt(c.get("unknowns")),
                    _fmt(None if _number(c.get("calibration_rms_mm")) is None else c["calibration_rms_mm"] * 1e3, ".3g"),
                    _fmt(None if _number(c.get("cv_rms_mm")) is None else c["cv_rms_mm"] * 1e3, ".3g"),
                    spread,
                ]
            )
            if c.get("model") != chosen:
                dim.add(k)
        blocks.append(
            _Table(
                header=["model", "unknowns", "calibration RMS (µm)", "CV RMS (µm)", "fold RMS (µm)"],
                rows=rows,
                caption=f"{folds}-fold cross-validation by pose: each fold of poses held out, the model refitted on "
                "the others and the held-out points predicted; the chosen model is the one with the fewest unknowns "
                "whose CV mean squared error is within one standard error of the smallest",
                source="refine/points.json",
                text_columns=frozenset({0, 4}),
                dim_rows=frozenset(dim),
                tags={k: "(chosen)" for k, c in enumerate(candidates) if c.get("model") == chosen},
                note=f"Chosen: {reason}" if reason else "",
            )
        )
    return blocks


def _joint_model_blocks(document: dict | None) -> list:
    """The deployed refinement's joint-model parameters with their u."""
    blocks: list = []
    joint_model = (document or {}).get("joint_model") or {}
    parameters = [p for p in joint_model.get("parameters") or [] if isinstance(p, dict)]
    if parameters:
        masses = found if isinstance(found := joint_model.get("masses"), dict) else None
        source = (
            f"link masses: {masses.get('source') or 'given'}; payload {_fmt(_number(masses.get('payload_kg')), '.3g')} kg"
            if masses
            else "lumped form: the first moments are estimated from the data (the robot file gives no masses)"
        )
        blocks.append(_block("heading", text="Joint model of the deployed refinement"))
        blocks.append(
            _Table(
                header=["parameter", "group", "value", "u", "unit"],
                rows=[
                    [
                        str(p.get("name")),
                        str(p.get("group")),
                        _fmt(_number(p.get("value")), ".4g"),
                        _fmt(_number(p.get("u")), ".2g") if _number(p.get("u")) is not None else "",
                        str(p.get("unit")),
                    ]
                    for p in parameters
                ],
                caption="compliance k [rad/(N m)]: deflection = k x gravity torque; harmonic a, b [deg]: "
                "a sin(kq) + b cos(kq); u from the refinement's linearised covariance. " + source,
                source="refine/points.json",
                text_columns=frozenset({0, 1, 4}),
                dim_rows=frozenset(k for k, p in enumerate(parameters) if p.get("identified") is False),
            )
        )
    return blocks


def _validation_blocks(page: _Page, chosen: str) -> list:
    """The validation error of the nominal, the geometric and the deployed model."""
    blocks: list = []
    evaluation = page.json("evaluation/evaluation.json") or {}
    found = {
        row.get("parameter_set"): row
        for row in evaluation.get("rows") or []
        if isinstance(row, dict) and row.get("capture") == "validation" and row.get("view") == "points"
    }
    labels = (
        ("nominal", "nominal model (no calibration)"),
        ("geometric", "geometric refinement (points criterion)"),
        ("points", f"deployed refinement ({chosen or 'points criterion'})"),
    )
    rows = [
        [what, _length(_number(found[name].get("mean_error_mm"))), _length(_number(found[name].get("rms_error_mm"))),
         _length(_number(found[name].get("max_error_mm")))]
        for name, what in labels
        if name in found
    ]  # fmt: skip
    if rows:
        blocks.append(_block("heading", text="Validation error with and without the joint model"))
        blocks.append(
            _Table(
                header=["model", "mean", "RMS", "max"],
                rows=rows,
                caption="error at the held-out validation poses after a best-fit registration of each model's "
                "predicted points onto the measured ones (evaluation, points view); "
                "robotcal compensate commands the joints with the deployed model, so the robot then lands within "
                "this error of where it was taught",
                source="evaluation/evaluation.json",
                text_columns=frozenset({0}),
            )
        )
    return blocks


def _model(page: _Page) -> dict:
    document = page.json("refine/points.json")
    provenance = (document or {}).get("provenance")
    if not isinstance(provenance, dict):
        return {"present": False, "blocks_": [_block("not_run", what="refine/points.json")]}
    candidates, chosen, reason = _candidates(provenance)
    blocks: list = []
    blocks += _candidates_table(candidates, chosen, reason)
    blocks += _joint_model_blocks(document)
    blocks += _validation_blocks(page, chosen)
    check = page.summary.consistency
    if check is not None:
        blocks.append(
            _block(
                "note",
                text=f"Consistency of the deployed model at {check.poses} validation poses: expected RMS "
                f"{_length(check.expected_rms_mm)} (uncertainty {_length(check.predicted_rms_mm)} with the instrument "
                f"{_length(check.instrument_rms_mm)}{_uncompensated(check)}), observed {_length(check.observed_rms_mm)} "
                f"({_observed(check.base_frame)}), ratio "
                f"{_fmt(check.ratio, '.3g')}: {check.verdict}.",
            )
        )
    return {"present": bool(blocks), "blocks_": blocks}


def _uncompensated(check) -> str:
    """``" and the measured joint errors the model cannot compensate X"`` when the check counted them."""
    if check.uncompensated_rms_mm is None:
        return ""
    return f" and the measured joint errors the deployed model cannot compensate {_length(check.uncompensated_rms_mm)}"

"""The parameters section: nominal, truth, CPA, refined and Monte Carlo values per parameter, refinement residuals."""

from __future__ import annotations

from robotcal.kinematics.model import ANGLE_KINDS, DISPLAY_UNITS, LENGTH_KINDS, PARAMETER_KINDS
from robotcal.report.page import (
    _block,
    _difference,
    _facts,
    _fmt,
    _is_param,
    _joint_model_units,
    _length,
    _number,
    _Page,
    _param_order,
    _scaled,
    _Table,
)


def _parameter_values(data: dict | None) -> tuple[dict, set, set]:
    """``name -> value`` [mm, deg], identified names and structurally fixed names of a parameter JSON."""
    values: dict[str, float] = {}
    fixed: set[str] = set()
    if not data or not isinstance(data.get("joints"), list):
        return values, set(), fixed
    for i, joint in enumerate(data["joints"]):
        if not isinstance(joint, dict):
            continue
        for kind in PARAMETER_KINDS:
            number = _number(joint.get(kind))
            if number is not None:
                values[f"J{i + 1}.{kind}"] = number
        if "hayati" in joint:
            fixed.add(f"J{i + 1}.d" if joint["hayati"] else f"J{i + 1}.beta")
    identified = data.get("identified")
    return values, set(identified) if isinstance(identified, list) else set(), fixed


def _statistics(data: dict | None) -> dict:
    """``name -> parameter entry`` of a Monte Carlo's ``parameters.json`` (``parameters`` list)."""
    parameters = (data or {}).get("parameters")
    if not isinstance(parameters, list):
        return {}
    return {p["name"]: p for p in parameters if isinstance(p, dict) and isinstance(p.get("name"), str)}


def _refinement_rms(page: _Page, label: str, data: dict) -> list:
    """Which RMS is which, for one refinement: the criterion's, the points', and the validation's."""
    provenance = found if isinstance(found := data.get("provenance"), dict) else {}
    convergence = found if isinstance(found := provenance.get("convergence"), dict) else {}
    history = found if isinstance(found := convergence.get("rms_mm"), list) else []
    final = _number(history[-1]) if history else None
    residuals, points = provenance.get("residuals"), provenance.get("points")
    distance = "point distance |T p − m|" if label == "points" else "distance error |D model − D measured|"
    rows = []
    if final is not None:
        rows.append(
            [
                "criterion RMS (convergence figure)",
                _length(final),
                f"√(2·cost/m): RMS of the {residuals} residuals, per coordinate"
                if label == "points"
                else f"√(2·cost/m): RMS of the {residuals} distance residuals",
            ]
        )
    rms = _number(provenance.get("residual_rms_mm"))
    if rms is not None:
        what = (
            f"at the {points} capture points: a distance in 3-D, so about √3 × the per-coordinate RMS"
            if label == "points"
            else "over the capture's point pairs: the same residuals as the criterion's"
        )
        rows.append([f"RMS {distance}", _length(rms), what])
    evaluation = page.json("evaluation/evaluation.json") or {}
    for row in evaluation.get("rows") or []:
        if isinstance(row, dict) and row.get("parameter_set") == label and row.get("capture") == "validation":
            if row.get("view") == "points" and _number(row.get("rms_error_mm")) is not None:
                rows.append(
                    [
                        "validation RMS error",
                        _length(_number(row["rms_error_mm"])),
                        f"RMS of the {row.get('n_errors')} validation point errors after a best-fit registration "
                        "(evaluation, points view): not fitted, so the honest figure",
                    ]
                )
    if not rows:
        return []
    return [
        _Table(
            header=["RMS", "value", "what it is"],
            rows=rows,
            caption=f"The RMS figures of the {label} refinement",
            text_columns=frozenset({0, 2}),
        )
    ]


Column = tuple[str, dict, str]


def _value_columns(cpa: dict | None, truth: dict | None, refined: dict, mc: dict) -> tuple[list[Column], set, set]:
    """The value columns (label, ``name -> value``, format) of the parameters tables, the identified names and the
    structurally fixed names."""
    cpa_values, identified, fixed = _parameter_values(cpa)
    truth_values = _parameter_values(truth)[0]
    nominal = {}
    for stats in mc.values():
        nominal.update(
            {n: _number(p.get("nominal")) for n, p in stats.items() if _number(p.get("nominal")) is not None}
        )
    values: list[Column] = [("nominal", nominal, ".4f")] if nominal else []
    if truth_values:
        values.append(("truth", truth_values, ".4f"))
    if cpa_values:
        values.append(("CPA", cpa_values, ".4f"))
        if truth_values:
            values.append(
                (
                    "CPA − truth",
                    {k: _difference(k, v, truth_values[k]) for k, v in cpa_values.items() if k in truth_values},
                    ".4f",
                )
            )
    for label, data in refined.items():
        found, more, more_fixed = _parameter_values(data)
        if found:
            values.append((f"refined ({label})", found, ".4f"))
            identified |= more
            fixed |= more_fixed
    return values, identified, fixed


def _uncertainty_columns(page: _Page, mc: dict, identified: set) -> tuple[list[Column], set]:
    """The Monte Carlo columns (mean, u, interval of each model) and the identified names (the Monte Carlo's when no
    parameter file names them)."""
    uncertainty: list[Column] = []
    for folder, model in (("uncertainty-refined", "refined"), ("uncertainty", "CPA")):
        stats = mc[folder]
        if not stats:
            continue
        coverage = _number((page.json(f"{folder}/parameters.json") or {}).get("coverage"))
        share = f"{_fmt(coverage * 100, '.3g')} % " if coverage else ""
        uncertainty += [
            (f"{model} MC mean", {n: _number(p.get("mean")) for n, p in stats.items()}, ".4f"),
            (f"{model} u", {n: _number(p.get("std_uncertainty")) for n, p in stats.items()}, ".3g"),
            (
                f"{model} {share}interval",
                {n: (_number(p.get("coverage_low")), _number(p.get("coverage_high"))) for n, p in stats.items()},
                ".4f",
            ),
        ]
        if not identified:
            identified = {n for n, p in stats.items() if p.get("identified") is True}
    return uncertainty, identified


def _parameter_tables(names: list[str], values: list[Column], uncertainty: list[Column], identified: set) -> list:
    """The lengths' and the angles' tables of values and of Monte Carlo uncertainty."""
    blocks: list[dict | _Table] = []
    for unit, kinds, title in (
        (DISPLAY_UNITS["length"], LENGTH_KINDS, "Lengths"),
        (DISPLAY_UNITS["angle"], ANGLE_KINDS, "Angles"),
    ):
        group = [n for n in names if n.split(".")[1] in kinds]
        if not group:
            continue
        dim = frozenset(r for r, n in enumerate(group) if identified and n not in identified)
        tags = {r: "(not identified)" for r in dim}
        blocks.append(_block("heading", text=f"{title} ({unit})"))
        for columns, what in ((values, "values"), (uncertainty, "Monte Carlo uncertainty")):
            if not columns:
                continue
            rows = []
            for name in group:
                row = [name]
                for _, found, spec in columns:
                    value = found.get(name)
                    if isinstance(value, tuple):
                        row.append(
                            f"{_fmt(value[0], spec, exponent=False)} … {_fmt(value[1], spec, exponent=False)}"
                            if None not in value
                            else ""
                        )
                    else:
                        row.append(_fmt(value, spec, exponent=spec != ".4f") if value is not None else "")
                rows.append(row)
            blocks.append(
                _Table(
                    header=["parameter"] + [f"{label} ({unit})" for label, _, _ in columns],
                    rows=rows,
                    caption=f"{what}, every one in {unit}; grey rows are not identified and stay nominal",
                    text_columns=frozenset({0}),
                    dim_rows=dim,
                    tags=tags,
                )
            )
    return blocks


def _cpa_blocks(cpa: dict | None) -> list:
    """The CPA circle fits, the adjacent axes and the CPA provenance."""
    blocks: list = []
    provenance = (cpa or {}).get("provenance") if isinstance((cpa or {}).get("provenance"), dict) else None
    if provenance is not None:
        circles = [c for c in provenance.get("circles") or [] if isinstance(c, dict)]
        if circles:
            blocks.append(_block("heading", text="CPA circle fits"))
            blocks.append(
                _Table(
                    header=["circle", "points", "radius (mm)", "plane RMS (µm)", "circle RMS (µm)"],
                    rows=[
                        [
                            str(c.get("circle", "")),
                            str(c.get("points", "")),
                            _fmt(_number(c.get("radius_mm")), ".4f"),
                            _fmt(
                                _scaled(c.get("plane_rms_mm"), 1e3),
                                ".3g",
                            ),
                            _fmt(
                                _scaled(c.get("circle_rms_mm"), 1e3),
                                ".3g",
                            ),
                        ]
                        for c in circles
                    ],
                    caption="plane RMS: distance of the points to the fitted plane; circle RMS: in-plane distance to "
                    "the fitted circle",
                    source="cpa/parameters.json",
                )
            )
        pairs = provenance.get("line_pairs")
        if isinstance(pairs, list) and pairs:
            blocks.append(_block("note", text="Adjacent joint axes: " + "; ".join(str(p) for p in pairs) + "."))
        blocks += _facts(
            provenance,
            caption="CPA provenance",
            source="cpa/parameters.json",
            skip=("circles", "line_pairs", "versions", "tracker_from_base"),
        )
    return blocks


def _parameters(page: _Page) -> dict:
    cpa = page.json("cpa/parameters.json")
    truth = page.json("truth.json")
    refined = {label: page.json(f"refine/{label}.json") for label in ("points", "distances")}
    mc = {
        folder: _statistics(page.json(f"{folder}/parameters.json")) for folder in ("uncertainty-refined", "uncertainty")
    }
    if cpa is None and not any(mc.values()) and not any(refined.values()):
        return {"present": False, "blocks_": [_block("not_run", what="cpa/parameters.json")]}
    values, identified, fixed = _value_columns(cpa, truth, refined, mc)
    uncertainty, identified = _uncertainty_columns(page, mc, identified)
    names = sorted({n for _, found, _ in values + uncertainty for n in found if _is_param(n)} - fixed, key=_param_order)
    blocks = _parameter_tables(names, values, uncertainty, identified)
    blocks += _cpa_blocks(cpa)
    for label, data in refined.items():
        if data and isinstance(data.get("provenance"), dict):
            blocks.append(_block("heading", text=f"Refinement ({label} criterion)"))
            blocks += _refinement_rms(page, label, data)
            blocks += _facts(
                data["provenance"],
                caption="provenance",
                source=f"refine/{label}.json",
                skip=("versions", "convergence", "correlation", "tracker_from_base"),
                units=_joint_model_units(data),
            )
    return {"present": True, "blocks_": blocks}

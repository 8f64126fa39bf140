"""The sections of the stage folders: evaluation, joints, Monte Carlo, TCP, workspace, ISO 9283, planning."""

from __future__ import annotations

from pathlib import PurePosixPath

from robotcal.report.page import (
    _NOISE_FLOOR,
    _block,
    _captions,
    _cell,
    _csv,
    _facts,
    _figures,
    _fmt,
    _histogram_caption,
    _label,
    _number,
    _Page,
    _scaled,
    _stage,
    _Table,
)


def _evaluation(page: _Page) -> dict:
    if not page.has("evaluation"):
        return {"present": False, "blocks_": [_block("not_run", what="evaluation/")]}
    return {
        "present": True,
        "blocks_": _stage(page, "evaluation", first_csv=("evaluation.csv",), first_png=("convergence.png",)),
    }


def _noise_floors(page: _Page) -> tuple[dict, str]:
    """``(joint -> noise floor [µm], document)``: the ``noise_floor_um`` column of ``joints/summary.csv`` (one
    row per joint; older runs have none)."""
    for name, key in (("joints/summary.csv", "joint"),):
        table = page.table(name)
        if table is not None and {key, "noise_floor_um"} <= set(table.header):
            floors: dict[str, float] = {}
            for joint, value in zip(table.column(key), table.column("noise_floor_um"), strict=True):
                floor = _number(value)
                if floor is not None:
                    floors.setdefault(joint, floor)
            return floors, name
    return {}, ""


def _joints(page: _Page) -> dict:
    if not page.has("joints"):
        return {"present": False, "blocks_": [_block("not_run", what="joints/")]}
    blocks: list[dict | _Table] = []
    summary = page.table("joints/summary.csv")
    floors, floor_source = _noise_floors(page)
    if summary is not None:
        records = summary.records()
        fits = [
            "joint",
            "points",
            "radius_mm",
            "plane_rms_mm",
            "circle_rms_mm",
            "axial_min_mm",
            "axial_max_mm",
            "radial_min_mm",
            "radial_max_mm",
        ]
        um = {name for name in fits if name.endswith("_mm") and name != "radius_mm"}
        present = [c for c in fits if c in summary.header]
        blocks.append(_block("heading", text="Circle fits and eccentricity"))
        blocks.append(
            _Table(
                header=[_label(c[:-3] + "_um") if c in um else _label(c) for c in present],
                rows=[
                    [
                        _fmt(_scaled(r[c], 1e3), ".3g") if c in um and _number(r[c]) is not None else _cell(r[c])
                        for c in present
                    ]
                    for r in records
                ],
                caption="per joint; small lengths in µm",
                source="joints/summary.csv",
            )
        )
        lash = [
            c
            for c in ("backlash_mean_mm", "backlash_min_mm", "backlash_max_mm", "backlash_std_mm")
            if c in summary.header
        ]
        if lash:
            header = ["joint", "pairs"] + [_label(c[:-3] + "_um") for c in lash]
            rows = []
            for r in records:
                row = [r.get("joint", ""), r.get("pairs", "")]
                row += [_fmt(_scaled(r[c], 1e3), ".3g") if _number(r[c]) is not None else r[c] for c in lash]
                if "backlash_angle_mean_deg" in summary.header:
                    row.append(_cell(r["backlash_angle_mean_deg"]))
                if floors:
                    floor, mean = floors.get(r.get("joint")), _number(r.get("backlash_mean_mm"))
                    row.append(_fmt(floor, ".3g") if floor is not None else "n/a")
                    ratio = mean * 1e3 / floor if floor and mean is not None else None
                    row.append(_fmt(ratio, ".2f", exponent=False))
                rows.append(row)
            if "backlash_angle_mean_deg" in summary.header:
                header.append("backlash angle mean (deg)")
            if floors:
                header += ["noise floor (µm)", "mean / floor"]
            blocks.append(_block("heading", text="Backlash"))
            blocks.append(
                _Table(
                    header=header,
                    rows=rows,
                    caption="per joint: magnitude of return − forward at the same reading; "
                    + (f"{_NOISE_FLOOR} (from {floor_source})" if floors else "no noise floor in this run"),
                    source="joints/summary.csv",
                )
            )
    captions = _captions(page, "joints")
    per_point = [n for n in page.children("joints", ".csv") if n != "joints/summary.csv"]
    if per_point:
        blocks.append(
            _block("note", text="Per point and per pair of forward and return points: " + ", ".join(per_point) + ".")
        )
    blocks += _figures(page, "joints", captions=captions, first=("backlash_magnitude.png", "backlash_xyz.png"))
    for name in page.children("joints", ".json"):
        blocks += _facts(page.json(name), source=name, skip=("figures", "versions", "joints"))
    return {"present": True, "blocks_": blocks, "noise_floor": bool(floors)}


#: Columns of a TCP uncertainty's CSV shown: the pose, then these.
_TCP_COLUMNS = ("pose", "name", "nominal", "mean", "std_uncertainty", "coverage_low", "coverage_high", "lpu_std_uncertainty")
#: Columns of a Monte Carlo's parameters.csv shown in the report (the file holds more): the deployed value beside
#: the estimate and the bias subtracted from it (issue 29), its u and the correction's, the interval (around it).
_MC_COLUMNS = (
    "name",
    "nominal",
    "estimate",
    "bias",
    "deployed",
    "mean",
    "std_uncertainty",
    "correction_u",
    "coverage_low",
    "coverage_high",
    "lpu_std_uncertainty",
    "identified",
)


def _histogram_captions(page: _Page, folder: str, names: list[str]) -> dict:
    """``{hist_J<n>.png: caption}`` of a Monte Carlo folder: what its histograms draw, from its ``parameters.json``
    (``model``, ``criterion``, ``linearised``: null when the Monte Carlo computed no linearised comparison, as
    ``robotcal run``'s refined one); a ``"figures"`` caption of the folder's JSON documents wins."""
    data = page.json(f"{folder}/parameters.json") or {}
    model = found if isinstance(found := data.get("model"), str) else None
    linearised = isinstance(data["linearised"], dict) if "linearised" in data else None
    refinement = f"refine/{data.get('criterion')}.json" if isinstance(data.get("criterion"), str) else None
    captions = {}
    for name in names:
        stem = PurePosixPath(name).stem
        captions[PurePosixPath(name).name] = _histogram_caption(
            stem.removeprefix("hist_"),
            model=model,
            linearised=linearised,
            refinement=refinement if refinement and page.has(refinement) else None,
        )
    return {**captions, **_captions(page, folder)}


def _montecarlo(page: _Page) -> dict:
    if not page.has("uncertainty") and not page.has("uncertainty-refined"):
        return {"present": False, "blocks_": [_block("not_run", what="uncertainty/")]}
    models = []
    for folder, title in (
        ("uncertainty-refined", "Refined model (deployed)"),
        ("uncertainty", "CPA model (thesis ch. 5.2.3)"),
    ):
        if not page.has(folder):
            models.append({"title": title, "folder": folder, "blocks_": [_block("not_run", what=folder + "/")]})
            continue
        blocks = _facts(
            page.json(f"{folder}/parameters.json"),
            caption="settings and outcome",
            source=f"{folder}/parameters.json",
            skip=("figures", "versions", "scenario", "parameters", "covariance", "correlation", "linearised"),
        )
        pngs = page.children(folder, ".png")
        histograms = [n for n in pngs if PurePosixPath(n).name.startswith("hist_")]
        blocks += _figures(page, folder, names=histograms, captions=_histogram_captions(page, folder, histograms))
        blocks += _figures(page, folder, names=[n for n in pngs if not PurePosixPath(n).name.startswith("hist_")])
        blocks += _csv(
            page,
            f"{folder}/parameters.csv",
            caption="parameter statistics; the interval is the one for the measurand, the draws' interval moved by "
            "twice their bias and widened by the bias correction's uncertainty (correction_u): around the deployed "
            "value (estimate - bias) where one is deployed (the file has more columns: bias_treatment, the draws' own "
            "interval, min, max, shortest interval, linearised interval)",
            columns=_MC_COLUMNS,
            rows_limit=200,
        )
        for name in page.children(folder, ".csv"):
            if name != f"{folder}/parameters.csv":
                blocks += _csv(page, name)
        models.append({"title": title, "folder": folder, "blocks_": blocks})
    return {"present": True, "models": models}


def _tcp_stage(page: _Page, folder: str) -> list:
    return _stage(
        page,
        folder,
        first_csv=("tcp.csv",),
        csv_options={"tcp.csv": {"columns": _TCP_COLUMNS, "caption": "the file has more columns: min, max"}},
    )


def _tcp(page: _Page) -> dict:
    parts = []
    for sub, title in (("pose", "At the pose"), ("trajectory", "Along the trajectory")):
        folder = f"tcp/{sub}"
        present = page.has(folder)
        blocks = _tcp_stage(page, folder) if present else [_block("not_run", what=folder + "/")]
        parts.append({"title": title, "blocks_": blocks, "present": present})
    consistency = _facts(
        page.json("tcp/consistency.json"), caption="validation consistency", source="tcp/consistency.json"
    )
    return {"present": any(p["present"] for p in parts), "parts": parts, "consistency": consistency}


def _workspace(page: _Page) -> dict:
    if not page.has("tcp/workspace"):
        return {"present": False, "blocks_": [_block("not_run", what="tcp/workspace/")]}
    return {"present": True, "blocks_": _tcp_stage(page, "tcp/workspace")}


def _iso9283(page: _Page) -> dict:
    if not page.has("iso9283"):
        return {"present": False, "blocks_": [_block("not_run", what="iso9283/")]}
    units = "units: APx, APy, APz, AP, l_bar, S_l, RP, AD, RD in mm; APa, APb, APc, RPa, RPb, RPc in deg"
    blocks = _stage(
        page,
        "iso9283",
        first_csv=("iso9283.csv",),
        first_png=("iso9283.png",),
        csv_options={"iso9283.csv": {"caption": units}},
    )
    return {"present": True, "blocks_": blocks}


def _planning(page: _Page) -> dict:
    if not page.has("plan"):
        return {"present": False, "blocks_": [_block("not_run", what="plan/")]}
    check = _stage(page, "plan", first_csv=("plan_check.csv",), first_png=("plan_check.png",))
    if page.has("plan/sensitivity"):
        sensitivity = _stage(page, "plan/sensitivity")
    else:
        sensitivity = [_block("not_run", what="plan/sensitivity/")]
    return {"present": True, "check": check, "sensitivity": sensitivity}

"""The self-contained HTML calibration report of a run (docs/results.md, docs/report.md).

The report renders from the run object, never from the run folder: :func:`render_report` takes a
:class:`~robotcal.io.results.run_folder.RunResult` (``record``: ``run.json``; ``documents``: every output by its path
in the run folder, JSON objects as dicts, CSV files as :class:`~robotcal.io.results.run_folder.Table`, figures as
Paths) and reads no file but the PNG bytes of the figures it embeds. :func:`build_report` is
:func:`robotcal.io.results.run_folder.read_run` (the one reader of a run folder) + :func:`render_report` + an
atomic write, for ``robotcal report DIR``.

How a page is built: one *builder* per section (:mod:`robotcal.report.sections`) turns the run
(:class:`~robotcal.report.page._Page`) into the section's template context (plain strings, numbers and
lists: tables and figures as blocks); one Jinja2 template per section (``templates/<section>.html.j2``,
autoescaped) lays it out, with the shared macros of ``templates/macros.html.j2``; ``templates/page.html.j2``
holds the page, the CSS and scripts of ``assets/`` inlined. Nothing is recomputed from the documents except
the circle fits of the 3-D view; the headline figures come from :attr:`RunResult.summary
<robotcal.io.results.run_folder.RunResult>` (or :func:`robotcal.io.results.run_summary.summarise` when the run has none).

The page needs no network: CSS and scripts are inline, figures are PNG ``data:`` URIs, and a
Content-Security-Policy forbids any other source. Its last script checks that every figure decoded and
every canvas drew, then sets ``<body data-status="ok">`` (or ``"error"``, with the messages in
``#rc-errors``); the browser test reads that.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

from robotcal.io.atomic import atomic_write_text
from robotcal.io.results.run_folder import REPORT_NAME, RunResult, read_run
from robotcal.report import installed_version, template_environment
from robotcal.report.page import _Page
from robotcal.report.sections.model import _model
from robotcal.report.sections.parameters import _parameters
from robotcal.report.sections.provenance import _provenance
from robotcal.report.sections.stages import _evaluation, _iso9283, _joints, _montecarlo, _planning, _tcp, _workspace
from robotcal.report.sections.summary import _summary
from robotcal.report.sections.view3d import _view3d
from robotcal.report.viewer3d import asset_text

__all__ = ["REPORT_NAME", "Report", "ReportSection", "render_report", "build_report"]

_CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'"


# --------------------------------------------------------------------------------------------------
# results


@dataclass(frozen=True, slots=True, kw_only=True)
class ReportSection:
    """One section of the report: anchor, title and whether its stage had results."""

    id: str
    title: str
    present: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class Report:
    """A rendered report.

    Attributes
    ----------
    html : str
        The whole page.
    path : Path or None
        Where it was written (None from :func:`render_report`).
    sections : tuple of ReportSection
    figures : int
        PNG figures embedded.
    canvases : int
        Interactive 3-D views.
    problems : tuple of str
        Documents that could not be read (``RunResult.problems``) or used (a figure that is not a PNG);
        each is also shown in the page.
    """

    html: str
    path: Path | None = None
    sections: tuple[ReportSection, ...] = ()
    figures: int = 0
    canvases: int = 0
    problems: tuple[str, ...] = ()


_SECTIONS = (
    ("summary", "Summary", _summary),
    ("parameters", "Parameters", _parameters),
    ("model", "Model choice", _model),
    ("evaluation", "Evaluation and convergence", _evaluation),
    ("joints", "Joint diagnostics", _joints),
    ("montecarlo", "Monte Carlo uncertainty", _montecarlo),
    ("tcp", "TCP uncertainty", _tcp),
    ("workspace", "Workspace map", _workspace),
    ("iso9283", "ISO 9283 accuracy and repeatability", _iso9283),
    ("planning", "Capture planning", _planning),
    ("view3d", "3-D view of the capture", _view3d),
    ("provenance", "Provenance", _provenance),
)


def render_report(result: RunResult) -> Report:
    """Render the report of a run as one HTML string, without writing anything.

    Parameters
    ----------
    result : RunResult
        The run (from :func:`robotcal.run_calibration` or :func:`robotcal.read_run`).
        Every stage is optional. No file is read but the PNG figures among its documents.

    Returns
    -------
    Report

    Examples
    --------
    A run held in memory, here built by hand: a workspace map and nothing else.

    >>> from robotcal.io.results.run_folder import RunResult
    >>> workspace = {"poses": [{"position_uncertainty_mm": u} for u in (0.002, 0.004)]}
    >>> report = render_report(RunResult(documents={"tcp/workspace/tcp.json": workspace}))
    >>> [section.id for section in report.sections if section.present]
    ['summary', 'workspace', 'provenance']
    >>> "3 µm / 3.9 µm" in report.html  # median / 95th percentile of the two poses
    True
    """
    from markupsafe import Markup

    page = _Page(result)
    environment = template_environment()
    sections, bodies = [], []
    for anchor, title, build in _SECTIONS:
        context = build(page)
        sections.append(ReportSection(id=anchor, title=title, present=bool(context["present"])))
        if "viewer" in context:
            context["viewer"] = Markup(context["viewer"])  # render_viewer escapes what it embeds (tested)
        body = environment.get_template(f"{anchor}.html.j2").render(**context)
        bodies.append({"id": anchor, "title": title, "body": Markup(body)})
    robot = page.record.get("robot") or (page.json("cpa/parameters.json") or {}).get("robot") or "robot"
    scenario = found if isinstance(found := page.record.get("scenario"), dict) else {}
    canvases = sum(str(b["body"]).count("<canvas") for b in bodies)
    html = environment.get_template("page.html.j2").render(
        title=f"Calibration report: {robot}",
        scenario=scenario.get("name") if isinstance(scenario.get("name"), str) else None,
        folder=result.folder.name if result.folder is not None else None,
        version=installed_version(),
        csp=_CSP,
        sections=sections,
        bodies=bodies,
        problems=page.problems,
        css=Markup(asset_text("report.css")),
        errors_js=Markup(asset_text("errors.js")),
        viewer_js=Markup(asset_text("viewer3d.js")) if canvases else None,
        check_js=Markup(asset_text("check.js")),
    )
    return Report(
        html=html,
        sections=tuple(sections),
        figures=page.figures,
        canvases=canvases,
        problems=tuple(page.problems),
    )


def build_report(run_dir: str | os.PathLike[str], out: str | os.PathLike[str] | None = None) -> Report:
    """Read the run folder ``run_dir``, render its report and write it atomically to ``out``.

    Parameters
    ----------
    run_dir : path
        A run folder (docs/results.md), read by :func:`robotcal.read_run`.
    out : path, optional
        The HTML file to write (default ``run_dir/report.html``).

    Returns
    -------
    Report
        With ``path`` set. See :func:`render_report`.

    Raises
    ------
    InputError
        ``run_dir`` is missing, not a folder, or holds none of the result files.
    """
    report = render_report(read_run(run_dir))
    path = Path(out) if out is not None else Path(run_dir) / REPORT_NAME
    atomic_write_text(path, report.html)
    return replace(report, path=path)

"""The tester's review of the report (issue 30): what the captions, cards and tables say, their units and numbers.

The run folder is tests/report/report_run.py's (conftest.py); each test changes its own copy where it needs a
document the synthetic run does not hold.
"""

from __future__ import annotations

import json
import re
import shutil

from report_run import load_run

from robotcal.report.html import render_report


def _render(folder) -> str:
    return render_report(load_run(folder)).html


def _section(page: str, anchor: str) -> str:
    start = page.index(f'<section id="{anchor}">')
    return page[start : page.index("</section>", start)]


def _edit_json(path, change) -> None:
    document = json.loads(path.read_text(encoding="utf-8"))
    change(document)
    path.write_text(json.dumps(document), encoding="utf-8")


def _captions(page: str) -> dict[str, str]:
    """``{figure document: its caption}`` of the page's figures."""
    return {source: caption.strip() for caption, source in re.findall(r"<figcaption>([^<]*)<code>([^<]+)</code>", page)}


def test_histogram_captions_say_what_each_monte_carlo_drew(run_folder):
    """The refined Monte Carlo of `robotcal run` computes no linearised comparison (``"linearised": null``), so its
    histograms have no GUM density and their noise-free value is the refinement's: the caption says so, while
    the CPA one, which has it, promises the density."""
    shutil.copy(run_folder / "uncertainty" / "hist_J1.png", run_folder / "uncertainty-refined" / "hist_J1.png")
    _edit_json(run_folder / "uncertainty" / "parameters.json", lambda d: d.update(linearised={"step_mm": 0.001}))
    _edit_json(run_folder / "uncertainty-refined" / "parameters.json", lambda d: d.update(linearised=None))
    captions = _captions(_render(run_folder))
    cpa, refined = captions["uncertainty/hist_J1.png"], captions["uncertainty-refined/hist_J1.png"]
    assert "the linearised (GUM) density" in cpa and "noise-free CPA value" in cpa
    assert "with the linearised" not in refined and "the linearised (GUM) density" not in refined
    assert "no linearised (GUM) density" in refined
    assert "noise-free refined value" in refined and "CPA value" not in refined

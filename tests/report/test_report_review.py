"""The tester's review of the report (issue 30): what the captions, cards and tables say, their units and numbers.

The run folder is tests/report/report_run.py's (conftest.py); each test changes its own copy where it needs a
document the synthetic run does not hold.
"""

from __future__ import annotations

import html
import json
import re
import shutil

from report_run import CONSISTENCY_MM, U_REFINED_ANGLE_DEG, U_REFINED_LENGTH_MM, load_run

from robotcal.report.html import render_report
from robotcal.report.page import _length


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


def _cards(page: str) -> dict[str, tuple[str, str]]:
    """``{card label: (value, detail)}`` of the summary's headline cards (text unescaped)."""
    found = re.findall(
        r'<div class="rc-label">(.*?)</div><div class="rc-value">(.*?)</div>.*?<div class="rc-detail">(.*?)</div>',
        _section(page, "summary"),
    )
    return {html.unescape(label): (html.unescape(value), html.unescape(detail)) for label, value, detail in found}


def test_the_validation_card_says_which_error_its_numbers_are(run_folder):
    """The headline's mean errors are after a best-fit registration (the evaluation's points view); the card says
    so, gives the RMS of the same errors, and the absolute figures of the consistency check (base frame given,
    no registration), so that the page's three numbers for the deployed model are told apart."""
    cards = _cards(_render(run_folder))
    label = next(name for name in cards if "validation error" in name and "before" in name)
    value, detail = cards[label]
    assert value == "900 µm → 50 µm" and "mean" in label
    assert "after a best-fit registration" in detail and "points view" in detail
    # evaluation.csv of the fixture: RMS = 1.1 x mean at the validation points
    assert f"RMS {_length(0.9 * 1.1)} → {_length(0.05 * 1.1)}" in detail
    # the consistency check's observed error: absolute, with the given base frame
    assert f"RMS {_length(CONSISTENCY_MM['observed_rms_mm'])}" in detail
    assert "base frame given, no registration" in detail
    _, consistency = cards["validation RMS error, expected → observed"]
    assert "base frame given, no registration" in consistency and "after a best-fit registration" in consistency


def test_the_model_section_labels_its_validation_numbers(run_folder):
    """The model-choice section shows the registered errors (table) and the absolute RMS (consistency note): each
    says which it is."""
    section = html.unescape(_section(_render(run_folder), "model"))
    assert "after a best-fit registration" in section
    assert f"observed {_length(CONSISTENCY_MM['observed_rms_mm'])} (RMS, base frame given, no registration)" in section


def test_the_largest_uncertainty_is_over_the_parameters_the_refinement_determines(run_folder):
    """A refinement marks the free parameters that take up the effect of held ones ``confounded`` (only their
    combination is determined): the headline's largest u is over the others, and the card names the confounded
    one that is larger."""
    refined = run_folder / "uncertainty-refined" / "parameters.json"

    def widen(document):
        for entry in document["parameters"]:
            if entry["name"] in ("J5.a", "J5.theta"):
                entry["std_uncertainty"] = 0.009 if entry["unit"] == "mm" else 0.005

    _edit_json(refined, widen)
    _edit_json(
        run_folder / "refine" / "points.json",
        lambda d: d["provenance"].update(held=["J5.alpha"], confounded=["J5.d", "J5.theta", "J5.a"]),
    )
    cards = _cards(_render(run_folder))
    value, detail = cards["largest standard uncertainty, lengths"]
    assert value == _length(U_REFINED_LENGTH_MM)
    assert "J5.a" in detail and "confounded" in detail and _length(0.009) in detail
    assert "parameters the refinement determines" in detail
    value, detail = cards["largest standard uncertainty, angles"]
    assert value == f"{U_REFINED_ANGLE_DEG:.3g}°"
    assert "J5.theta" in detail and "confounded" in detail and "0.005°" in detail


def _facts(section: str) -> dict[str, tuple[str, str]]:
    """``{entry: (value, unit)}`` of the entry/value/unit tables of a section."""
    rows = re.findall(
        r'<tr><td class="rc-text">([^<]*)</td><td class="rc-text">([^<]*)</td><td class="rc-text">([^<]*)</td></tr>',
        section,
    )
    return {html.unescape(entry): (html.unescape(value), html.unescape(unit)) for entry, value, unit in rows}


def test_joint_model_uncertainties_carry_their_unit(run_folder):
    """A refinement's ``standard_uncertainty`` of a joint-model parameter (``J2.k``) is one entry, in the unit the
    document's joint model gives it, not a pure number."""

    def extend(document):
        document["provenance"]["standard_uncertainty"]["J2.k"] = 2.5e-07
        document["provenance"]["standard_uncertainty"]["J3.a1"] = 0.0012
        document["joint_model"] = {"parameters": [{"name": "J2.k", "unit": "rad/(N m)", "value": 1e-05, "u": 2.5e-07}]}

    _edit_json(run_folder / "refine" / "points.json", extend)
    facts = _facts(_section(_render(run_folder), "parameters"))
    assert facts["standard uncertainty › J2.k"][1] == "rad/(N m)"
    assert facts["standard uncertainty › J3.a1"][1] == "deg"  # a harmonic coefficient
    assert "standard uncertainty › J2 › k" not in facts


def test_micrometres_are_written_one_way(run_folder):
    """The stages' one-line results say "um" (console text); the page writes µm, as everywhere else."""
    _edit_json(
        run_folder / "run.json",
        lambda d: d["stages"].update(refine={"status": "done", "detail": "points RMS 11.5 um, distances RMS 13.9 um"}),
    )
    page = html.unescape(_render(run_folder))
    assert "points RMS 11.5 µm, distances RMS 13.9 µm" in _section(page, "summary")
    assert re.search(r"\d um\b", page) is None


def test_cpa_minus_truth_in_fixed_notation(run_folder):
    page = _render(run_folder)
    section = _section(page, "parameters")
    result = load_run(run_folder)
    cpa, truth = result.json("cpa/parameters.json"), result.json("truth.json")
    for joint, kind in ((1, "a"), (2, "a"), (3, "theta"), (2, "beta")):
        cells = re.search(rf'<tr[^>]*><td class="rc-text">J{joint}\.{kind}</td>(.*?)</tr>', section).group(1)
        difference = re.findall(r"<td[^>]*>(.*?)</td>", cells)[3]
        assert "e" not in difference
        expected = cpa["joints"][joint - 1][kind] - truth["joints"][joint - 1][kind]
        assert difference == f"{expected:.4f}".replace("-0.0000", "0.0000")


def test_percentages_are_rounded(run_folder):
    """evaluation.csv's improvement_pct: one decimal (52.4 %, not 52.4319 %)."""
    tables = re.findall(r"<table>.*?</table>", _section(_render(run_folder), "evaluation"), re.S)
    section = next(table for table in tables if "<code>evaluation/evaluation.csv</code>" in table)
    header = re.search(r"<thead><tr>(.*?)</tr></thead>", section).group(1)
    column = re.findall(r"<th[^>]*>(.*?)</th>", header).index("improvement (%)")
    shown = [re.findall(r"<td[^>]*>(.*?)</td>", row)[column] for row in re.findall(r"<tr>(<td.*?)</tr>", section)]
    assert shown and all(re.fullmatch(r"-?\d+\.\d", value) for value in shown), shown
    assert "86.7" in shown  # cpa: 100 (1 - 0.12 / 0.9)


def test_long_provenance_tables_show_every_entry_folded(run_folder):
    """A provenance of 90 entries is shown whole (no "First 60 of 90 rows"), in a table folded under a summary."""
    extra = {f"entry_{k:02d}": k for k in range(80)}
    _edit_json(run_folder / "refine" / "points.json", lambda d: d["provenance"].update(extra))
    section = _section(_render(run_folder), "parameters")
    assert "First 60" not in section and "rows; the file holds them all" not in section
    facts = _facts(section)
    assert all(f"entry {k:02d}" in facts for k in range(80))
    fold = re.search(r"<details class=\"rc-fold\"><summary>([^<]*)</summary>(.*?)</details>", section, re.S)
    assert fold and "entry_79" not in fold.group(1) and "entry 79" in fold.group(2)
    assert re.search(r"\d+ entries", fold.group(1))


def test_only_cells_with_a_long_token_may_break_it_anywhere(run_folder):
    """A word is never broken over two lines ("uncertaint y" in the stage table): text cells wrap between words,
    and only a cell holding a token longer than a column (a path) may break inside it. The browser test
    (test_browser.py) checks the rendered page; this checks the page's rules without a browser."""
    page = _render(run_folder)
    css = re.search(r"<style>(.*?)</style>", page, re.S).group(1)
    text_rule = re.search(r"td\.rc-text \{([^}]*)\}", css).group(1)
    assert "anywhere" not in text_rule and "break-word" in text_rule
    assert re.search(r"td\.rc-long \{[^}]*overflow-wrap: anywhere", css)
    assert '<td class="rc-text">uncertainty</td>' in _section(page, "summary")
    long_source = re.search(r'<td class="rc-text( rc-long)?">/calibration_runs_of_the_welding_cell', page)
    assert long_source and long_source.group(1) == " rc-long"

"""The report in a real headless Chromium: every figure rendered, the 3-D view drew, no console errors.

No DevTools protocol is needed: the page's own scripts record script errors, failed resources and
console errors/warnings, mark every ``<img>`` with ``data-loaded`` and every canvas with
``data-rendered``/``data-ink``, and set ``<body data-status>``. ``--dump-dom`` (after a virtual-time
budget that lets the load event fire) returns that DOM; ``--enable-logging=stderr`` additionally
prints every console message as a ``CONSOLE`` line, and the report logs nothing when all is well.
A screenshot of the first 4000 px is saved under the test's tmp dir.

Chromium is Debian's ``chromium`` package (``.ci/run`` installs it when missing); the test is
skipped only where no Chromium binary exists.
"""

from __future__ import annotations

import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from robotcal.report.html import build_report

#: Appended to a copy of the page by the layout test: after the load event, the tables whose content is wider
#: than their box (they would scroll sideways) and the page's own width, as attributes of <body>.
LAYOUT_PROBE = """<script>window.addEventListener("load", function () { setTimeout(function () {
  var folds = document.querySelectorAll("details");  // long tables are folded: measure them open
  for (var f = 0; f < folds.length; f++) folds[f].open = true;
  var wide = [], wraps = document.querySelectorAll(".rc-table-wrap");
  for (var i = 0; i < wraps.length; i++) {
    if (wraps[i].scrollWidth > wraps[i].clientWidth) {
      var caption = wraps[i].querySelector("caption");
      var name = caption ? caption.textContent : "table " + i;
      wide.push(name + ": " + wraps[i].scrollWidth + " px in " + wraps[i].clientWidth + " px");
    }
  }
  // words broken over two lines in a table cell (issue 30: "uncertaint y"): a run of letters whose text
  // ranges lie on more than one line; cells holding a token longer than a column (rc-long) may break it
  var split = [], cells = document.querySelectorAll("th, td");
  for (var c = 0; c < cells.length; c++) {
    if (cells[c].classList.contains("rc-long")) continue;
    var walker = document.createTreeWalker(cells[c], NodeFilter.SHOW_TEXT), node;
    while ((node = walker.nextNode())) {
      var pattern = /[A-Za-z\u00b5]{2,}/g, match;
      while ((match = pattern.exec(node.data))) {
        var range = document.createRange();
        range.setStart(node, match.index);
        range.setEnd(node, match.index + match[0].length);
        var rects = range.getClientRects(), tops = {};
        for (var r = 0; r < rects.length; r++) if (rects[r].width > 0) tops[Math.round(rects[r].top)] = 1;
        if (Object.keys(tops).length > 1) split.push(match[0]);
      }
    }
  }
  document.body.setAttribute("data-split-words", split.join(" | "));
  document.body.setAttribute("data-tables", String(wraps.length));
  document.body.setAttribute("data-wide-tables", wide.join(" | "));
  document.body.setAttribute("data-page-width", String(document.documentElement.scrollWidth));
}, 0); });</script>"""


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None


CHROMIUM = _chromium()
pytestmark = pytest.mark.skipif(
    CHROMIUM is None,
    reason="no Chromium binary (`chromium`): install Debian's chromium package (.ci/run does) to run the browser test",
)

FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-quic",
    "--no-first-run",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
]


def _run_chromium(page: Path, profile: Path, *extra: str) -> subprocess.CompletedProcess:
    command = [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", "--virtual-time-budget=10000", *extra, page.as_uri()]
    result = subprocess.run(command, capture_output=True, text=True, timeout=180, check=False)
    assert result.returncode == 0, f"chromium failed ({result.returncode}): {result.stderr[-2000:]}"
    return result


def _load(page: Path, tmp_path: Path, *extra: str) -> tuple[dict, str, list[str]]:
    """``(body attributes, dumped DOM, console lines)`` of ``page`` after loading it in Chromium."""
    result = _run_chromium(page, tmp_path / "profile-dom", "--enable-logging=stderr", "--v=0", *extra, "--dump-dom")
    body = re.search(r"<body([^>]*)>", result.stdout)
    assert body, f"no <body> in the dumped DOM: {result.stdout[:500]}"
    attributes = dict(re.findall(r'([\w-]+)="([^"]*)"', body.group(1)))
    console = [line for line in result.stderr.splitlines() if ":CONSOLE" in line]
    return attributes, result.stdout, console


def test_report_renders_in_headless_chromium(run_folder, tmp_path):
    report = build_report(run_folder)
    body, dom, console = _load(report.path, tmp_path)
    errors = re.search(r'<pre id="rc-errors"[^>]*>(.*?)</pre>', dom, re.S)
    assert console == [], console
    assert body["data-status"] == "ok", (body, errors.group(1) if errors else dom[-2000:])
    assert body["data-errors"] == "0" and errors.group(1) == ""
    # every embedded figure decoded with a non-zero width, and the 3-D view drew on its canvas
    assert body["data-figures"] == body["data-figures-ok"] == str(report.figures) == "5"
    assert body["data-canvases"] == body["data-canvases-ok"] == "1"
    images = re.findall(r"<img [^>]*>", dom)
    assert len(images) == 5 and all('data-loaded="1"' in image for image in images)
    ink = re.search(r'<canvas [^>]*data-ink="(\d+)"', dom)
    assert ink and int(ink.group(1)) > 5000, "the 3-D view is (nearly) blank"
    # the legend was built by the viewer script: one entry per circle plus the four toggles
    assert dom.count('class="rc-legend-item"') == 6 + 4

    screenshot = tmp_path / "report.png"
    _run_chromium(report.path, tmp_path / "profile-shot", f"--screenshot={screenshot}", "--window-size=1280,4000")
    header = screenshot.read_bytes()[:24]
    assert header[:8] == b"\x89PNG\r\n\x1a\n"
    assert struct.unpack(">II", header[16:24]) == (1280, 4000)


def test_self_check_catches_a_broken_figure_and_a_script_error(run_folder, tmp_path):
    """Negative control: the page's self-check must report what went wrong, so that "ok" means something."""
    report = build_report(run_folder)
    page = report.html.replace("data:image/png;base64,", "data:image/png;base64,AAAA", 1)
    page = page.replace("</main>", "<script>undefinedFunction();</script></main>", 1)
    broken = tmp_path / "broken.html"
    broken.write_text(page, encoding="utf-8")
    body, dom, console = _load(broken, tmp_path)
    assert body["data-status"] == "error"
    assert body["data-figures-ok"] == "4" and body["data-figures"] == "5"
    assert 'data-loaded="0"' in dom
    assert "undefinedFunction is not defined" in dom
    assert any("undefinedFunction" in line for line in console)


def test_layout_at_1280_px(run_folder, tmp_path):
    """Issue 13: every table readable without sideways scrolling at 1280 px; every section, the noise floor,
    the figures' captions and the 3-D view (drawn, no two labels overlapping) in the rendered page."""
    report = build_report(run_folder)
    probed = tmp_path / "probed.html"
    probed.write_text(report.html.replace("</body>", LAYOUT_PROBE + "</body>"), encoding="utf-8")
    body, dom, console = _load(probed, tmp_path, "--window-size=1280,4000")
    assert console == [] and body["data-status"] == "ok", body
    assert int(body["data-tables"]) > 20
    assert body["data-wide-tables"] == "", body["data-wide-tables"]
    assert body["data-split-words"] == "", body["data-split-words"]  # no word broken over two lines
    assert int(body["data-page-width"]) <= 1280
    for section in (
        "summary",
        "parameters",
        "evaluation",
        "joints",
        "montecarlo",
        "tcp",
        "workspace",
        "iso9283",
        "planning",
        "view3d",
        "provenance",
    ):
        assert re.search(rf'<section id="{section}"><h2>[^<]+</h2>', dom), section
    assert "<th>noise floor (µm)</th>" in dom
    caption = re.search(r"<figcaption>(Backlash magnitude[^<]*)<code>joints/backlash_magnitude.png", dom)
    assert caption and "(µm)" in caption.group(1) and "noise floor" in caption.group(1)
    canvas = re.search(r"<canvas [^>]*>", dom).group(0)
    attributes = dict(re.findall(r'([\w-]+)="([^"]*)"', canvas))
    assert int(attributes["data-ink"]) > 5000 and int(attributes["data-labels"]) >= 6
    assert attributes["data-label-overlaps"] == "0"


def test_layout_probe_sees_a_split_word(run_folder, tmp_path):
    """Negative control of the split-word check: a header squeezed to a few pixels breaks its word."""
    report = build_report(run_folder)
    page = report.html.replace("</body>", LAYOUT_PROBE + "</body>")
    page = page.replace("<th>", '<th style="min-width: 0; width: 1px; overflow-wrap: anywhere">', 1)
    probed = tmp_path / "split.html"
    probed.write_text(page, encoding="utf-8")
    body, _, _ = _load(probed, tmp_path, "--window-size=1280,4000")
    assert body["data-split-words"] != ""


def test_layout_probe_sees_a_wide_table(run_folder, tmp_path):
    """Negative control of the layout test: a table forced wider than the page is reported."""
    report = build_report(run_folder)
    page = report.html.replace("</body>", LAYOUT_PROBE + "</body>")
    page = page.replace("<table>", '<table style="min-width: 3000px">', 1)
    probed = tmp_path / "wide.html"
    probed.write_text(page, encoding="utf-8")
    body, _, _ = _load(probed, tmp_path, "--window-size=1280,4000")
    assert body["data-wide-tables"].count(" px in ") == 1

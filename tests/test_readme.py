"""The README's Python snippet runs as printed, in an empty folder and a fresh interpreter, and makes what it
says (issue 24: it read a ``capture.csv`` that nothing had made)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import robotcal

README = Path(__file__).resolve().parents[1] / "README.md"
#: Generous: the snippet takes ~20 s on an idle 2-core machine (a refined Monte Carlo and the demo run).
TIMEOUT_S = 900


def _python_snippet() -> str:
    text = README.read_text(encoding="utf-8")
    section = text.split("## Python API", 1)[1]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.DOTALL)
    assert len(blocks) == 1, "the README's Python API section holds one python block"
    return blocks[0]


def test_readme_python_snippet_runs_in_an_empty_folder(tmp_path):
    snippet = _python_snippet()
    assert 'read_capture("capture.csv"' in snippet  # what the issue found: it must also make that file
    script = tmp_path / "snippet.py"
    script.write_text(snippet, encoding="utf-8")
    work = tmp_path / "work"
    work.mkdir()
    result = subprocess.run(
        [sys.executable, str(script)], cwd=work, capture_output=True, text=True, timeout=TIMEOUT_S
    )
    assert result.returncode == 0, f"README snippet failed:\n{result.stdout}\n{result.stderr}"
    scenario = robotcal.load_scenario("kr5-demo")
    assert robotcal.read_capture(work / "capture.csv", n_joints=6).n_points == 270
    assert robotcal.read_parameters(work / "refined.json", scenario.robot).identified.any()
    assert (work / "run" / "report.html").is_file()
    assert "how good: mean validation error" in result.stdout

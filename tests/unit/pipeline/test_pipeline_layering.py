"""The pipeline sits below the CLI and the report: nothing in robotcal.pipeline or robotcal.report imports
robotcal.cli, and `import robotcal.pipeline` is light (names load lazily)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import robotcal

PACKAGE = Path(robotcal.__file__).parent


def _imported_modules(path: Path) -> set[str]:
    """Every module an ``import`` or ``from ... import`` statement of ``path`` names, at any depth (lazy too)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def test_pipeline_and_report_sources_never_import_the_cli():
    offenders = []
    for package in ("pipeline", "report"):
        for path in sorted((PACKAGE / package).glob("*.py")):
            bad = sorted(name for name in _imported_modules(path) if name.split(".")[:2] == ["robotcal", "cli"])
            offenders += [f"{path.relative_to(PACKAGE)}: {name}" for name in bad]
    assert offenders == []


def test_pipeline_reaches_the_report_only_through_run_calibration():
    """Nothing below imports upward: at any depth (lazy imports included) the pipeline imports no module of
    robotcal.report but the one exception, run.py rendering the report (robotcal.report.html) as its last stage;
    the plots (robotcal.plots, below the pipeline) import neither the pipeline, the report nor the CLI."""
    offenders = []
    for path in sorted((PACKAGE / "pipeline").glob("*.py")):
        for name in sorted(_imported_modules(path)):
            if name.split(".")[:2] != ["robotcal", "report"]:
                continue
            if path.name == "run.py" and name in (
                "robotcal.report.html",
                "robotcal.report.html.render_report",
                "robotcal.report.html.load_templates",  # compiles the templates while the last figures are drawn
            ):
                continue
            offenders.append(f"pipeline/{path.name}: {name}")
    for path in sorted((PACKAGE / "plots").glob("*.py")):
        for name in sorted(_imported_modules(path)):
            if name.split(".")[:2] in (["robotcal", "pipeline"], ["robotcal", "report"], ["robotcal", "cli"]):
                offenders.append(f"plots/{path.name}: {name}")
    assert offenders == []
    # the detector sees a lazy import inside a function
    assert "robotcal.report.html" in _imported_modules(PACKAGE / "pipeline" / "run.py")


def test_importing_the_pipeline_loads_neither_the_cli_nor_plots():
    code = (
        "import sys\n"
        "import robotcal.pipeline\n"
        "light = sorted(m for m in ('numpy', 'matplotlib', 'robotcal.cli', 'robotcal.report') if m in sys.modules)\n"
        "from robotcal.pipeline import plan_run, read_run, run_calibration, RunResult, STAGES\n"
        "import robotcal.pipeline.stages, robotcal.pipeline.folder, robotcal.pipeline.run\n"
        "used = sorted(m for m in ('matplotlib', 'typer', 'rich', 'robotcal.cli', 'robotcal.report.html') if m in sys.modules)\n"
        "print(','.join(light) + ';' + ','.join(used))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == ";"

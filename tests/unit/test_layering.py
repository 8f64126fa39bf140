"""The numeric core never imports the CLI, I/O or plotting layers (STYLE.md "Layout")."""

from __future__ import annotations

import subprocess
import sys


def test_core_imports_no_edge_libraries():
    code = (
        "import sys\n"
        "import robotcal.geometry, robotcal.kinematics, robotcal.instruments, robotcal.simulation, robotcal.identification\n"
        "import robotcal.capture\n"
        "bad = sorted(m for m in ('matplotlib', 'typer', 'rich', 'pydantic', 'robotcal.io', 'robotcal.cli') if m in sys.modules)\n"
        "print(','.join(bad))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == ""

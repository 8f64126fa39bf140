"""Benchmark of the command line's start-up: ``robotcal --help``, ``--version`` and every command's ``--help``.

Plain script: ``python benchmarks/bench_cli_startup.py [--repeat N]`` runs each command N times
(default 15) as a fresh subprocess, as a user's shell does, and prints the median and the minimum
wall time. Issue 13 asks for ``robotcal --help`` <= 0.3 s.

Rows, besides the commands themselves:

- ``python -c pass`` and ``import typer``: the floor (interpreter start, then the CLI framework);
- ``eager --help``: the behaviour before the lazy registry, emulated on today's code by importing
  every command module (:func:`robotcal.cli.load_command` for each name of
  :data:`robotcal.cli.COMMANDS`) before printing the help, as ``robotcal/cli/__init__.py`` used to.

Before the lazy registry (commit before issue 13's CLI change), ``robotcal --help`` took 0.9-2.4 s
on the project's 2-core machine (measured by the lead; 1.9-2.2 s measured by H4 under load):
:data:`BEFORE` holds those figures for the table.

Issue 23 (2026-11-28, median of 10, 2 alternated rounds): ``robotcal --help`` 0.068-0.092 s before
(05de958), 0.074-0.083 s with issue 23 (c0e2034), 0.078-0.081 s at 385f86a; ``run --help`` 0.33-0.39 s,
0.86-0.89 s (it loaded the pipeline and the whole domain for two constants), 0.20-0.21 s (they live in
:mod:`robotcal.limits`).

Issue 30 (the 2-core machine under a load average of 7-8 from parallel work, median of 5 runs, measured by
the clidocs helper): every command's own ``--help`` took 0.13-0.82 s before (768769a: report 0.82, simulate 0.81,
compensate 0.76, refine 0.70, tcp 0.66, predict 0.66, joints 0.58, evaluate 0.58, identify 0.55, filter
0.54, export 0.47, iso9283 0.43-0.45; they imported numpy, the API or all of :mod:`robotcal.io` for their
help) and 0.13-0.26 s after (demo 0.26, report 0.24, the others 0.13-0.19): :mod:`robotcal.io` loads its
names on first use and the command modules import numpy, the API and the ``io`` modules in the command.
Since then the ``eager --help`` row (every command module imported) no longer shows the old behaviour:
0.71 s before, 0.22 s after.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from robotcal.cli import COMMANDS

#: ``robotcal --help`` before the lazy registry [s]: the range measured on the 2-core machine.
BEFORE = {"robotcal --help": "0.9-2.4", "robotcal run --help": "0.9-2.4 (same imports)", "robotcal --version": "n/a"}
#: Issue 13's target for ``robotcal --help`` [s].
TARGET = 0.3
#: Issue 30's target for every command's own ``--help`` [s].
COMMAND_HELP_TARGET = 0.3

EAGER_HELP = (
    "import sys; import robotcal.cli as cli; [cli.load_command(name) for name in cli.COMMANDS]; "
    "sys.argv = ['robotcal', '--help']; cli.main()"
)


def robotcal_command() -> list[str]:
    """The installed ``robotcal`` script beside this interpreter, else the same entry point through ``-c``."""
    script = Path(sys.executable).with_name("robotcal")
    if script.is_file() and os.access(script, os.X_OK):
        return [str(script)]
    found = shutil.which("robotcal")
    return [found] if found else [sys.executable, "-c", "from robotcal.cli import main; main()"]


def time_command(command: list[str], repeat: int) -> list[float]:
    """Wall times [s] of ``repeat`` runs of ``command`` (output discarded; a failure stops the benchmark)."""
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - started)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15, help="runs per command (median and minimum reported)")
    parser.add_argument("--no-commands", action="store_true", help="skip the --help of every command")
    args = parser.parse_args()
    robotcal = robotcal_command()
    rows = {
        "python -c pass": [sys.executable, "-c", "pass"],
        "python -c 'import typer'": [sys.executable, "-c", "import typer"],
        "robotcal --help": [*robotcal, "--help"],
        "robotcal --version": [*robotcal, "--version"],
        "robotcal run --help": [*robotcal, "run", "--help"],
        "eager --help (old behaviour)": [sys.executable, "-c", EAGER_HELP],
    }
    helps = [] if args.no_commands else [[name] for name in COMMANDS if name != "run"] + [["plan", "optimise"]]
    for path in helps:
        rows[f"robotcal {' '.join(path)} --help"] = [*robotcal, *path, "--help"]
    print(f"cpu cores: {os.cpu_count()}, load average: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'command':<30} {'median (s)':>10} {'min (s)':>8}  before (s)")
    medians = {}
    for label, command in rows.items():
        times = time_command(command, args.repeat)
        medians[label] = statistics.median(times)
        print(f"{label:<30} {medians[label]:>10.3f} {min(times):>8.3f}  {BEFORE.get(label, '')}")
    verdict = "met" if medians["robotcal --help"] <= TARGET else "NOT met"
    print(f"target robotcal --help <= {TARGET} s: {verdict}")
    commands = {label: median for label, median in medians.items() if label.startswith("robotcal ") and " " in label[9:]}
    if commands:
        slowest = max(commands, key=commands.get)
        verdict = "met" if commands[slowest] <= COMMAND_HELP_TARGET else "NOT met"
        print(f"target every command's --help <= {COMMAND_HELP_TARGET} s: {verdict} (slowest: {slowest}, {commands[slowest]:.3f} s)")


if __name__ == "__main__":
    main()

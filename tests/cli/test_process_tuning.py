"""The ``robotcal`` entry point's process settings: one BLAS thread unless the user chose, before numpy loads."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from robotcal.cli._common import BLAS_THREAD_VARIABLES, limit_blas_threads


@pytest.fixture
def clean_environment(monkeypatch):
    for variable in BLAS_THREAD_VARIABLES:
        monkeypatch.delenv(variable, raising=False)
    return monkeypatch


def test_unset_thread_variables_become_one(clean_environment):
    limit_blas_threads()  # (not tune_numeric_runtime: its allocator settings would stay for the whole session)
    assert {variable: os.environ[variable] for variable in BLAS_THREAD_VARIABLES} == dict.fromkeys(
        BLAS_THREAD_VARIABLES, "1"
    )


def test_a_users_choice_is_kept(clean_environment):
    clean_environment.setenv("OPENBLAS_NUM_THREADS", "4")
    limit_blas_threads()
    assert os.environ["OPENBLAS_NUM_THREADS"] == "4"
    assert os.environ["OMP_NUM_THREADS"] == "1"


def test_the_entry_point_sets_them_before_numpy_is_imported():
    """``robotcal --version`` through :func:`robotcal.cli.main` in a fresh interpreter: the variables are
    set, and numpy is not imported by the entry point itself (so the setting takes effect when it is)."""
    environment = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}
    code = (
        "import os, sys\n"
        "from robotcal.cli import main\n"
        "sys.argv = ['robotcal', '--version']\n"
        "try:\n    main()\nexcept SystemExit:\n    pass\n"
        "print(os.environ.get('OPENBLAS_NUM_THREADS'), 'numpy' in sys.modules)\n"
    )
    completed = subprocess.run([sys.executable, "-c", code], env=environment, capture_output=True, text=True, check=True)
    assert completed.stdout.strip().splitlines()[-1] == "1 False"

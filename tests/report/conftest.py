"""Fixtures of the report tests: a run folder built once per session, copied per test."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from report_run import make_run_folder


@pytest.fixture(scope="session")
def _run_folder_template(tmp_path_factory) -> Path:
    return make_run_folder(tmp_path_factory.mktemp("run-template") / "run")


@pytest.fixture
def run_folder(_run_folder_template, tmp_path) -> Path:
    """A fresh copy of the complete run folder, which the test may change."""
    return Path(shutil.copytree(_run_folder_template, tmp_path / "run"))

"""Shared test configuration: slow statistical tests run only with ``-m slow``."""

from __future__ import annotations

import pytest


def pytest_collection_modifyitems(config, items):
    if config.getoption("-m"):
        return
    skip = pytest.mark.skip(reason="slow statistical test: run with -m slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)

"""Issue 30, item 5: ``plan optimise --generations 1`` printed "2.3474 -> 2.9194 mm (0.8x lower)" for a plan that
made the uncertainty worse. The summary line says "higher" / "no better" when it is; a gain keeps "Nx lower"."""

from __future__ import annotations

import pytest

from robotcal.cli.plan import optimise_summary


def _said(baseline, optimised):
    return optimise_summary(baseline, optimised, draws=10_000, evaluations=9, executor="local (1 worker)")


def test_the_testers_case_says_higher():
    line = _said(2.3474, 2.9194)
    assert "2.3474 -> 2.9194 mm (24 % higher: no better than the baseline)" in line
    assert "lower" not in line and "0.8x" not in line
    assert line.startswith("Monte Carlo (10000 draws): workspace p95 TCP position uncertainty ")
    assert line.endswith("; 9 candidates on local (1 worker)")


@pytest.mark.parametrize(
    ("baseline", "optimised", "wording"),
    [
        (2.9194, 1.2000, "(2.4x lower)"),
        (2.0000, 1.9000, "(5.0 % lower)"),  # a small gain: no "1.1x"
        (2.0000, 2.00001, "(no better: the same at this precision)"),
        (2.0000, 1.99998, "(no better: the same at this precision)"),
        (0.0, 0.5, "(higher: no better than the baseline)"),
        (0.5, 0.0, "(lower)"),
    ],
)
def test_the_wording_follows_the_numbers(baseline, optimised, wording):
    line = _said(baseline, optimised)
    assert wording in line, line
    assert "x lower" not in line or optimised * 1.1 <= baseline

"""TCP figures refuse a result without draws with the package's InputError."""

from __future__ import annotations

import numpy as np
import pytest

from robotcal.errors import InputError
from robotcal.io import load_robot
from robotcal.report.tcp import plot_tcp_histograms, plot_tcp_scatter
from robotcal.uncertainty.tcp import propagate_to_tcp

ROBOT = load_robot("kuka-kr5-sixx-r650-krc")


@pytest.mark.parametrize("plot", [plot_tcp_scatter, plot_tcp_histograms])
def test_figures_of_draws_need_keep_draws(plot, tmp_path):
    rng = np.random.default_rng(0)
    draws = ROBOT.nominal[None] + rng.normal(0.0, 1e-3, (20, ROBOT.n_joints, 5)) * ~ROBOT.structurally_fixed
    result = propagate_to_tcp(ROBOT, draws, np.deg2rad([10.0, -80.0, 100.0, 20.0, 50.0, -30.0]))
    with pytest.raises(InputError, match="keep_draws=True"):
        plot(result, tmp_path / "figure.png")
    assert not (tmp_path / "figure.png").exists()

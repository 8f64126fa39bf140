"""Figure of an ISO 9283 pose test: pose accuracy AP and repeatability RP per test pose and model."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robotcal.plots.figures import new_figure, save_figure, set_margins

__all__ = ["plot_iso_results"]


def plot_iso_results(results: dict, path: Path) -> Path:
    """Grouped bars of AP per test pose (one colour per model) with RP drawn as a tick above each bar [um].

    ``results``: ``{model: Iso9283Result}`` (mm inside; the figure is in micrometres).
    """
    figure, axes = new_figure(1, 1, width_in=7.5, height_in=3.6, layout=None)
    set_margins(figure, left=0.72, right=0.1, bottom=0.3, top=0.28)  # fixed [in]: no constrained layout pass
    models = list(results)
    n_poses = next(iter(results.values())).ap.shape[0]
    width = 0.8 / max(len(models), 1)
    x = np.arange(n_poses)
    for k, model in enumerate(models):
        r = results[model]
        positions = x - 0.4 + width * (k + 0.5)
        axes.bar(positions, r.ap * 1e3, width=width * 0.9, label=f"{model}: AP")
        axes.errorbar(positions, r.ap * 1e3, yerr=[np.zeros(n_poses), r.rp * 1e3], fmt="none", ecolor="k", lw=0.8,
                      capsize=2, label="RP (bar above AP)" if k == 0 else None)  # fmt: skip
    axes.set_xticks(x, [f"P{k + 1}" for k in range(n_poses)])
    axes.set_ylabel("AP, RP (µm)")
    axes.set_title("ISO 9283 pose accuracy AP and repeatability RP per test pose", y=1.0)  # fixed: no overlap search
    axes.legend(fontsize="x-small", ncol=2)
    return save_figure(figure, path)

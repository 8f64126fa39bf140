"""Figures: the matplotlib plots every stage writes beside its files (joints, Monte Carlo histograms, TCP,
planning, ISO 9283, convergence), all through :mod:`robotcal.plots.figures` (Agg canvas, fixed size, atomic
PNG writes).

Below the pipeline: the stages of :mod:`robotcal.pipeline` and the commands call these; they import only the
numeric core and :mod:`robotcal.io` (never the pipeline, the report or the CLI). The HTML report
(:mod:`robotcal.report`) embeds the PNG files they wrote.
"""

__all__ = ["background", "figures", "iso9283", "joints", "montecarlo", "planning", "refine", "tcp"]

"""The calibration pipeline as a library: plan a run, run it, write and read its folder."""

from robotcal.pipeline.result import Document, RunResult, Table

__all__ = ["Document", "RunResult", "Table"]

"""Identification: Circle Point Analysis (and, later, least-squares refinement)."""

from robotcal.identification.cpa import CPABatch, CPAOptions, CPAResult, identify_cpa, identify_cpa_batch, prepare_cpa

__all__ = ["CPABatch", "CPAOptions", "CPAResult", "identify_cpa", "identify_cpa_batch", "prepare_cpa"]

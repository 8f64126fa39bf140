"""Identification: Circle Point Analysis (:mod:`.cpa`), least-squares refinement (:mod:`.refine`), observability."""

from robotcal.identification.cpa import CPABatch, CPAOptions, CPAResult, identify_cpa, identify_cpa_batch, prepare_cpa

__all__ = ["CPABatch", "CPAOptions", "CPAResult", "identify_cpa", "identify_cpa_batch", "prepare_cpa"]

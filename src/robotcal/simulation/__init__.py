"""Simulation: capture plans and the synthetic Circle Point generator (thesis ch. 5.2.1)."""

from robotcal.simulation.generator import JointErrorModel, simulate_capture
from robotcal.simulation.plan import CapturePlan

__all__ = ["CapturePlan", "JointErrorModel", "simulate_capture"]

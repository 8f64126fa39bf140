"""Uncertainty: GUM Supplement 1 Monte Carlo of the calibration, its linearised comparison, and the
propagation of parameter draws to the TCP (thesis ch. 5.2.3 and 5.3)."""

"""Capture planning (thesis 4.5.2, 5.2.4, 6.2): cell check, robot programs, sensitivity, optimisation."""

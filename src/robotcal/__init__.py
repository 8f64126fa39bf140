"""robotcal: kinematic calibration of serial robots by Circle Point Analysis, with GUM-S1 uncertainty."""

__version__ = "0.1.0"

"""pmsm-hil: hardware-in-the-loop tool for PMSM drives."""

__version__ = "0.1.0"

"""Photograph-validation and calibration workbench for wave-optical rendering."""

__version__ = "0.1.0"

"""Synthetic raw photographs with known truth (issue 6): the sensor model and DNG files."""

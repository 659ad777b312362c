"""Photograph-validation and calibration workbench for wave-optical rendering.

This package is the face: the command line (``cli``), the demo and, later, the planner
and verification runs. The shared kernel lives in ``workbench.core``; the libraries
(rcwa, renderer, calibration, datasets_synthetic, reports) import only that.
"""

from workbench.core.version import __version__

__all__ = ["__version__"]

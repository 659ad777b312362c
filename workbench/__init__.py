"""Photograph-validation and calibration workbench for wave-optical rendering.

This package is the face: the command line (``cli``, with one module per command in
``commands``), the verification run from photos to reports (``verify``, its run folder and
stages in ``verify_run``) and its score against a synthetic dataset's truth (``score``),
the demo (``demo``), the built-ins and what a table holds in words (``catalog``) and
plain-text tables of results (``report_text``). The planner itself is the renderer's
(renderer.trace.planner; ``workbench plan`` prints it). The shared kernel lives in
``workbench.core``; the libraries (rcwa, renderer, calibration, datasets_synthetic,
reports) import only that.
"""

from workbench.core.version import __version__

__all__ = ["__version__"]

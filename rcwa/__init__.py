"""RCWA: rigorous coupled-wave analysis of 1D and 2D periodic multilayers.

The C++ core (rcwa._core) computes layer eigenmodes and the stack solution; this package
reads structures, builds the Fourier matrices and turns amplitudes into efficiencies.
See docs/architecture.md and workbench.core.conventions for units, signs and frames.
"""

from __future__ import annotations

import ctypes
import importlib
import os

__all__ = ["Structure", "Layer", "solve", "SolveResult", "OrderResult", "load_structure", "BUILTIN_STRUCTURES"]


def _preload_openblas() -> None:
    """Load libscipy_openblas from its pip package so the extension finds it at run time."""
    try:
        import scipy_openblas32
    except ImportError:  # pragma: no cover - a dependency of the package
        return
    path = os.path.join(scipy_openblas32.get_lib_dir(), "libscipy_openblas.so")
    if os.path.exists(path):
        ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)


_preload_openblas()

# The public names, imported on first use: so that importing a submodule (rcwa.materials,
# say) loads neither the solver nor the C++ core (tests/rcwa/test_materials.py).
_LAZY = {
    "Structure": "rcwa.structure",
    "Layer": "rcwa.structure",
    "load_structure": "rcwa.structure",
    "BUILTIN_STRUCTURES": "rcwa.structure",
    "solve": "rcwa.solver",
    "SolveResult": "rcwa.result",
    "OrderResult": "rcwa.result",
}


def __getattr__(name: str):  # PEP 562: import submodules on first use
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value  # later look-ups skip this function (rcwa.solve is called per solve)
        return value
    raise AttributeError(f"module 'rcwa' has no attribute {name!r}")

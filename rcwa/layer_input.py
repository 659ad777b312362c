"""The layers as the C++ core receives them, checked where they enter.

A layer crosses into the core (rcwa/cpp/sweep.hpp, ``LayerInput``) as its kind, its
thickness times k0, the permittivity of a uniform layer and the Fourier matrices of a
patterned one. :class:`LayerInput` checks every field on creation, in the manner of
fmmax's ``LayerSolveResult.__post_init__``: a wrong kind, count, shape or dtype raises
``ValueError`` naming the field, what was expected and what came, before anything reaches
C++ (which checks again, and raises ``ValueError`` too). These are the solver's own
products, not a user's input, so a failure here is a bug, not a ``UserInputError``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rcwa import _core

LayerKind = _core.LayerKind

# The Fourier matrices each kind carries, in the core's order (rcwa/cpp/modes.hpp): the
# Laurent matrix [[eps]] and the in-plane effective permittivity tensor of the rule (for a
# lamellar layer with inverse_rule, [[1/eps]] in place of Exx).
MATRIX_NAMES: dict[_core.LayerKind, tuple[str, ...]] = {
    LayerKind.UNIFORM: (),
    LayerKind.LAMELLAR: ("E", "Exx"),
    LayerKind.GENERAL: ("E", "Exx", "Exy", "Eyx", "Eyy"),
}
MATRIX_DTYPE = np.dtype(np.complex128)


def _fail(field_name: str, expected: str, got: Any) -> ValueError:
    return ValueError(f"LayerInput.{field_name}: expected {expected}, got {got!r}")


def _check_kind(kind: object) -> None:
    if not isinstance(kind, LayerKind):
        raise _fail("kind", f"a LayerKind, one of {[k.name for k in LayerKind]}", kind)


@dataclass(frozen=True, eq=False)  # eq=False: identity, since numpy arrays have no truth value
class LayerInput:
    """One layer of a stack, from the superstrate down, as the core receives it.

    kind: ``LayerKind``: UNIFORM (no matrices), LAMELLAR (``E``, ``Exx``) or GENERAL (``E``, ``Exx``, ``Exy``, ``Eyx``, ``Eyy``).
    k0_thickness: thickness times ``k0 = 2 pi / lambda`` (radians), finite and >= 0.
    permittivity: relative permittivity of a uniform layer (unused otherwise).
    matrices: the kind's N x N complex128 Fourier matrices (rcwa.factorization).
    inverse_rule: a LAMELLAR layer given as ``E`` and ``[[1/eps]]`` (Li's inverse rule),
        whose ``Exx = [[1/eps]]^-1`` the core forms only where a TM family needs it.
    """

    kind: _core.LayerKind
    k0_thickness: float
    permittivity: complex = 0j
    matrices: tuple[np.ndarray, ...] = ()
    inverse_rule: bool = False
    core: _core.LayerInput = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _check_kind(self.kind)
        kind = self.kind
        if not isinstance(self.inverse_rule, bool) or (self.inverse_rule and kind != LayerKind.LAMELLAR):
            raise _fail("inverse_rule", "False, or True for a lamellar layer", self.inverse_rule)
        if isinstance(self.k0_thickness, bool) or not isinstance(self.k0_thickness, (int, float, np.floating)) \
                or not (math.isfinite(self.k0_thickness) and self.k0_thickness >= 0):
            raise _fail("k0_thickness", "a finite number >= 0", self.k0_thickness)
        if not isinstance(self.permittivity, (int, float, complex, np.number)) or not np.isfinite(self.permittivity):
            raise _fail("permittivity", "a finite complex number", self.permittivity)
        matrices = tuple(self.matrices)
        names = MATRIX_NAMES[kind]
        if len(matrices) != len(names):
            raise _fail("matrices", f"{len(names)} for a {kind.name.lower()} layer {names}", f"{len(matrices)} matrices")
        for i, (name, matrix) in enumerate(zip(names, matrices, strict=True)):
            _check_matrix(f"matrices[{i}] ({name})", matrix, matrices[0])
        object.__setattr__(self, "matrices", matrices)
        object.__setattr__(self, "core", _core.LayerInput(kind, float(self.k0_thickness), complex(self.permittivity),
                                                          list(matrices), self.inverse_rule))

    @classmethod
    def lamellar(cls, k0_thickness: float, period: float, segments: list[tuple[float, float, complex]],
                 harmonics: int, inverse_rule: bool = True) -> LayerInput:
        """A LAMELLAR layer whose matrices the core builds from its permittivity profile
        (``(x0, x1, eps)`` segments on ``[0, period)``; rcwa/cpp/profile.hpp): ``E`` and
        ``[[1/eps]]`` with ``inverse_rule``, else ``Exx = E``. The core checks what it builds
        (make_layer); ``matrices`` holds copies of its matrices."""
        core = _core.LayerInput.lamellar(float(k0_thickness), float(period), segments, int(harmonics), inverse_rule)
        layer = object.__new__(cls)
        for name, value in (("kind", LayerKind.LAMELLAR), ("k0_thickness", float(k0_thickness)), ("permittivity", 0j),
                            ("matrices", tuple(core.matrices)), ("inverse_rule", inverse_rule), ("core", core)):
            object.__setattr__(layer, name, value)
        return layer

    @property
    def size(self) -> int:
        """N, the number of harmonics the matrices are for (0 for a uniform layer)."""
        return self.matrices[0].shape[0] if self.matrices else 0


def _check_matrix(field_name: str, matrix: Any, first: np.ndarray) -> None:
    if not isinstance(matrix, np.ndarray):
        raise _fail(field_name, "a numpy array", type(matrix).__name__)
    if matrix.dtype != MATRIX_DTYPE:
        raise _fail(field_name, f"dtype {MATRIX_DTYPE}", str(matrix.dtype))
    n = first.shape[0] if first.ndim == 2 else 0
    if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1] or matrix.shape != first.shape or n < 1:
        expected = f"shape ({n}, {n}) like matrices[0]" if matrix is not first else "a square matrix (N, N), N >= 1"
        raise _fail(field_name, expected, matrix.shape)

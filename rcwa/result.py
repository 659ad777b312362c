"""Results of one RCWA solve: per-order efficiencies, amplitudes and directions."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np


@dataclass(frozen=True)
class OrderResult:
    """One diffraction order (m, n) for the polarization asked (``R``, ``T``), and per s/p.

    ``R``/``T`` are efficiencies (fractions of the incident power through a plane
    z = const). ``r_s``, ``t_s`` are outgoing amplitudes of the s part per unit incident
    amplitude, ``r_p``, ``t_p`` of the p part, for s incidence (``*_from_s``) and p
    incidence (``*_from_p``): s waves are measured by E along s-hat, p waves by h = Z0 H
    along s-hat. Directions are (theta, phi) in degrees: reflected orders from +z,
    transmitted orders from -z, azimuth from +x.
    """

    m: int
    n: int
    R: float
    T: float
    R_s: float
    R_p: float
    T_s: float
    T_p: float
    propagating_R: bool
    propagating_T: bool
    direction_R: tuple[float, float] | None
    direction_T: tuple[float, float] | None
    amplitudes: dict[str, complex] = field(repr=False, default_factory=dict)
    # (superstrate index, substrate index or NaN when it absorbs, cos of the incident polar angle):
    # what turns the amplitudes into power-normalised Jones matrices (rcwa.polarimetry)
    media: tuple[float, float, float] = field(repr=False, default=(math.nan, math.nan, math.nan))

    @classmethod
    def from_fields(cls, fields: dict[str, Any]) -> OrderResult:
        """The same object as ``OrderResult(**fields)`` (every field given), built without
        the frozen dataclass's one ``object.__setattr__`` per field: the solver makes one per
        retained order and solve, and this halves their cost (about 5 us each)."""
        if fields.keys() != _ORDER_FIELDS:
            raise TypeError(f"OrderResult.from_fields: expected the fields {sorted(_ORDER_FIELDS)}, got {sorted(fields)}")
        order = object.__new__(cls)
        order.__dict__.update(fields)
        return order

    @property
    def R_unpolarized(self) -> float:
        return 0.5 * (self.R_s + self.R_p)

    @property
    def T_unpolarized(self) -> float:
        return 0.5 * (self.T_s + self.T_p)

    def to_dict(self) -> dict[str, Any]:
        """Efficiencies and, for each propagating order, its direction (see
        :data:`DIRECTION_CONVENTION`); a non-propagating side has ``None``."""
        return {"m": self.m, "n": self.n, "R": self.R, "T": self.T,
                "direction_R": _direction(self.direction_R), "direction_T": _direction(self.direction_T)}


_ORDER_FIELDS = frozenset(OrderResult.__dataclass_fields__)

DIRECTION_CONVENTION = (
    "theta_deg, phi_deg of the order's direction of travel, in the medium it travels in: reflected orders in the "
    "superstrate (theta from +z, the surface normal into the superstrate), transmitted orders in the substrate "
    "(theta from -z); phi from +x (the grating vector) toward +y"
)


def _direction(direction: tuple[float, float] | None) -> dict[str, float] | None:
    return None if direction is None else {"theta_deg": float(direction[0]), "phi_deg": float(direction[1])}


@dataclass(frozen=True)
class SolveResult:
    """One solve's efficiencies: totals, every retained order's in ``all_orders`` (arrays),
    and the propagating orders as :class:`OrderResult` objects in ``orders``.

    ``orders`` is built from the solve's arrays on first use (``order_builder``; a
    :func:`functools.cached_property`): the objects cost about 5 us each, as much as the
    rest of a small 1D solve's Python, and sweeps, tables and totals never need them.
    """

    structure: str
    wavelength_nm: float
    theta_deg: float
    phi_deg: float
    pol: str
    orders_retained: tuple[int, ...]
    factorization: str
    R_total: float
    T_total: float
    absorption: float
    order_builder: Callable[[], list[OrderResult]] = field(repr=False, compare=False)
    all_orders: dict[str, np.ndarray] = field(repr=False, default_factory=dict)
    # The core's fast paths this solve took (rcwa.solver.solve, fast_paths): empty for the
    # general path; "te_tm_decoupled" (1D, k_y = 0: TE and TM on N x N blocks),
    # "single_polarization" (only the requested one solved; the other's values are NaN),
    # "hermitian_eigensolver" (lossless 1D layers solved as Hermitian problems),
    # "real_arithmetic" (of those, layers symmetric about a point, solved in real arithmetic),
    # "mirror_sectors" (a 2D cell's mirror-symmetry sectors, only those the incidence excites:
    # rcwa/cpp/sectors.hpp; with "single_polarization" for pol "s" or "p"),
    # "single_layer_direct" (one patterned layer's boundary conditions solved as one system:
    # rcwa/cpp/stack.cpp, solve_direct), "inverse_iteration" (lossy 1D layers below 75
    # harmonics: eigenvalues by QR, eigenvectors by inverse iteration, rcwa/cpp/linalg.hpp).
    fast_paths: tuple[str, ...] = ()

    @cached_property
    def orders(self) -> list[OrderResult]:
        """The propagating orders (on either side), in the solver's harmonic order."""
        return self.order_builder()

    def order(self, m: int, n: int = 0) -> OrderResult:
        for o in self.orders:
            if o.m == m and o.n == n:
                return o
        raise KeyError(f"order ({m}, {n}) does not propagate (or was not retained)")

    def to_dict(self) -> dict[str, Any]:
        return {
            "structure": self.structure,
            "wavelength_nm": self.wavelength_nm,
            "theta_deg": self.theta_deg,
            "phi_deg": self.phi_deg,
            "pol": self.pol,
            "orders_retained": list(self.orders_retained),
            "factorization": self.factorization,
            "R_total": self.R_total,
            "T_total": self.T_total,
            "absorption": self.absorption,
            "directions": DIRECTION_CONVENTION,
            "orders": [o.to_dict() for o in self.orders],
        }

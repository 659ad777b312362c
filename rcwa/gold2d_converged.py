"""Converged efficiencies of the paper's 2D gold block (built-in ``gold2d``), with error bars.

The cell (a 0.5 x 0.5 x 1 um gold block in a 1 um square period, air on both sides,
[Lange 2021, Fig. 6]) is solved at increasing truncation N x N for Li's rule [Li 1997],
the normal-vector rule [Schuster 2007] and Li's rule in the stretched coordinates of
adaptive spatial resolution [Granet 1999] (rcwa.asr; ``asr_table``) at 450, 550 and
650 nm, theta 0 and 30 deg (phi = 0), s and p, and T_total, T(0,0) and R_total are extrapolated to N -> infinity
(rcwa.extrapolation: a power law in 1/N fitted per parity class of (N - 1) / 2, with the
fit's standard error and the spread between extrapolation choices as the error bar).
High truncations are affordable because of the cell's mirrors: at normal incidence only
s is solved, in the one mirror sector it excites (an eighth of the unpolarized general
problem's eigen-solve size cubed), and p follows from the diagonal mirror
(rcwa.solve_cache); at 30 deg in the plane phi = 0 the y mirror halves the problem. Raw
solves are cached (rcwa.solve_cache), so a rerun only extrapolates.

Reciprocity [Petit 1980, Sec. 1.4.3] on converged values: order (1, 0) from (theta = 30,
phi = 0) leaves along k_x = sin 30 - lambda / Lambda; incidence from the reversed
direction, theta_b = asin|k_x| at phi = 0, sends its order (1, 0) back along the first
incidence, with the same efficiency, per polarization (in the plane phi = 0 the y
mirror keeps s and p apart for orders (m, 0)). The cell is also symmetric in z (air on
both sides), so transmitted orders obey it too. ``reciprocity`` compares the two
extrapolated efficiencies within their error bars.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import rcwa
from rcwa.extrapolation import Extrapolation, extrapolate
from rcwa.solve_cache import Direction, RawSolve, SolveCache, default_cache_path

WAVELENGTHS_NM = (450.0, 550.0, 650.0)
THETAS_DEG = (0.0, 30.0)
RULES = ("li", "nv")
POLARIZATIONS = ("s", "p")
QUANTITIES = ("T_total", "T00", "R_total")
# Truncations N x N solved for every direction, and beyond them where a direction's cost allows (docs/gold2d_convergence.md).
DENSE_ORDERS = tuple(range(9, 37, 2))
HIGH_ORDERS = {(550.0, 0.0): tuple(range(37, 63, 2)), (450.0, 0.0): tuple(range(37, 53, 2)),
               (650.0, 0.0): tuple(range(37, 53, 2)),
               **{(wl, 30.0): tuple(range(37, 49, 2)) for wl in WAVELENGTHS_NM}}
TAIL = 6  # truncations per parity class in the primary fit
# Adaptive spatial resolution (rcwa.asr; issue 29, item 2): a dense solver without mirror sectors, so
# its truncations stop at 35 x 35 (51-89 s a solve, both polarizations, on a loaded 2-core machine).
# Both rules in the stretched coordinates: Li's (ASR_RULE) and the normal-vector rule's (ASR_NV_RULE).
ASR_RULE, ASR_NV_RULE = "asr", "asr_nv"
ASR_ORDERS = DENSE_ORDERS
# The NV rule in stretched coordinates is published where it settles a question: at 550 nm, normal
# incidence, the bar; at 650 nm, normal incidence, where the uniform NV rule drifts away.
ASR_NV_DIRECTIONS = (Direction(550.0, 0.0), Direction(650.0, 0.0))


def open_cache(path: str | Path | None = None) -> SolveCache:
    """gold2d's raw solves in ``path`` (default: rcwa.solve_cache.default_cache_path)."""
    return SolveCache(path if path is not None else default_cache_path("gold2d"), rcwa.load_structure("gold2d"))


def directions() -> list[Direction]:
    return [Direction(wl, th) for wl in WAVELENGTHS_NM for th in THETAS_DEG]


def orders_for(direction: Direction, max_orders: int | None = None) -> tuple[int, ...]:
    """The truncations solved for ``direction`` (DENSE_ORDERS and its HIGH_ORDERS), up to ``max_orders``."""
    planned = DENSE_ORDERS + HIGH_ORDERS.get((direction.wavelength_nm, direction.theta_deg), ())
    return tuple(n for n in planned if max_orders is None or n <= max_orders)


def reverse_direction(wavelength_nm: float, theta_deg: float = 30.0, period_um: float = 1.0) -> tuple[Direction, int]:
    """The incidence that order (1, 0) from (theta, phi = 0) is reciprocal to, and the order m of
    it that returns (module docstring). Put at phi = 0 by the x mirror where the reversed wave
    vector points to -x (the order is then -1: the mirror maps m onto -m)."""
    kx = math.sin(math.radians(theta_deg)) - wavelength_nm / 1000.0 / period_um
    if abs(kx) >= 1.0:
        raise ValueError(f"reverse_direction: order (1, 0) does not propagate at {wavelength_nm} nm, {theta_deg} deg")
    return Direction(wavelength_nm, math.degrees(math.asin(abs(kx))), 0.0), (1 if kx < 0 else -1)


def quantity(raw: RawSolve, name: str, pol: int) -> float:
    """``name`` (QUANTITIES) of one raw solve, polarization 0 = s, 1 = p."""
    if name == "T_total":
        return raw.T_total[pol]
    if name == "R_total":
        return raw.R_total[pol]
    if name == "T00":
        return raw.efficiency("T", 0, 0, pol)
    raise ValueError(f"quantity: expected one of {QUANTITIES}, got {name!r}")


@dataclass(frozen=True)
class ConvergedValue:
    """One quantity's sequence over truncations and its extrapolated limit."""

    wavelength_nm: float
    theta_deg: float
    pol: str
    rule: str
    quantity: str
    orders: tuple[int, ...]
    values: tuple[float, ...]
    seconds: tuple[float, ...]
    peak_rss_bytes: tuple[int | None, ...]
    limit: Extrapolation

    def row(self) -> dict:
        """A flat row for CSV and JSON."""
        return {"wavelength_nm": self.wavelength_nm, "theta_deg": self.theta_deg, "pol": self.pol, "rule": self.rule,
                "quantity": self.quantity, "value": self.limit.value, "error": self.limit.error,
                "max_orders": max(self.orders), "value_at_max_orders": self.values[self.orders.index(max(self.orders))],
                "power": self.limit.fit.power}


def sequence(cache: SolveCache, direction: Direction, rule: str, orders: Iterable[int]) -> list[tuple[int, RawSolve]]:
    """The raw solves at ``orders`` (solved now where the cache lacks them)."""
    return [(n, cache.solve(direction, n, rule)) for n in orders]


def converge(cache: SolveCache, direction: Direction, rule: str, orders: tuple[int, ...], pol: str, name: str,
             tail: int = TAIL) -> ConvergedValue:
    """One quantity of one direction extrapolated over ``orders``."""
    solves = sequence(cache, direction, rule, orders)
    index = POLARIZATIONS.index(pol)
    values = tuple(quantity(raw, name, index) for _, raw in solves)
    return ConvergedValue(direction.wavelength_nm, direction.theta_deg, pol, rule, name, tuple(orders), values,
                          tuple(raw.seconds for _, raw in solves), tuple(raw.peak_rss_bytes for _, raw in solves),
                          extrapolate(orders, values, tail=tail))


def converged_table(cache: SolveCache, max_orders: int | None = None) -> list[ConvergedValue]:
    """Every direction, polarization, rule and quantity (at normal incidence s only: p equals it by the diagonal mirror)."""
    out = []
    for d in directions():
        for pol in POLARIZATIONS[:1] if d.theta_deg == 0.0 else POLARIZATIONS:
            for rule in RULES:
                for name in QUANTITIES:
                    out.append(converge(cache, d, rule, orders_for(d, max_orders), pol, name))
    return out


def asr_table(cache: SolveCache, max_orders: int | None = None, rule: str = ASR_RULE,
              only: Iterable[Direction] | None = None) -> list[ConvergedValue]:
    """converged_table's values for adaptive spatial resolution (``rule``: ASR_RULE or ASR_NV_RULE, over
    ASR_ORDERS), for every direction or ``only`` these."""
    orders = tuple(n for n in ASR_ORDERS if max_orders is None or n <= max_orders)
    return [converge(cache, d, rule, orders, pol, name) for d in (directions() if only is None else only)
            for pol in (POLARIZATIONS[:1] if d.theta_deg == 0.0 else POLARIZATIONS) for name in QUANTITIES]


@dataclass(frozen=True)
class ReciprocityCheck:
    wavelength_nm: float
    rule: str
    pol: str
    side: str  # "R" or "T"
    forward: Extrapolation
    backward: Extrapolation

    @property
    def difference(self) -> float:
        return abs(self.forward.value - self.backward.value)

    @property
    def within_errors(self) -> bool:
        return self.difference <= self.forward.error + self.backward.error


def reciprocity(cache: SolveCache, orders: tuple[int, ...] = DENSE_ORDERS, wavelengths: tuple[float, ...] = WAVELENGTHS_NM,
                rules: tuple[str, ...] = RULES) -> list[ReciprocityCheck]:
    """Order (1, 0) from (theta = 30, phi = 0) against its reciprocal incidence (module docstring), extrapolated."""
    checks = []
    for wl in wavelengths:
        a = Direction(wl, 30.0)
        b, m_b = reverse_direction(wl)
        for rule in rules:
            fa, fb = sequence(cache, a, rule, orders), sequence(cache, b, rule, orders)
            for i, pol in enumerate(POLARIZATIONS):
                for side in ("R", "T"):
                    ea = extrapolate(orders, [r.efficiency(side, 1, 0, i) for _, r in fa], tail=TAIL)
                    eb = extrapolate(orders, [r.efficiency(side, m_b, 0, i) for _, r in fb], tail=TAIL)
                    checks.append(ReciprocityCheck(wl, rule, pol, side, ea, eb))
    return checks

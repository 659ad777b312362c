"""Convergence of efficiencies with the number of retained harmonics, per factorization rule.

``make bench`` prints the curves (benchmarks/bench_convergence.py):

* a metallic lamellar grating in TM (the structure of [Li 1993] / [Granet 1996, Table 1]:
  index 0.22 + 6.71i, period = wavelength = 1 um, 30 deg, ridge width 0.5 um, depth
  0.1 um), where Li's inverse rule converges far faster than the Laurent rule
  ([Li 1996, Fig. 3]; [Lalanne 1996]);
* the paper's 2D gold block (built-in ``gold2d``): zero-order transmission at 550 nm,
  normal incidence, for the [Li 1997], normal-vector and Laurent rules.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import rcwa
from rcwa.structure import Structure

METAL_GRATING = {
    "period": [1.0], "superstrate": 1.0, "substrate": {"n": 0.22, "k": 6.71},
    "layers": [{"thickness": 0.1, "material": 1.0, "shapes": [{"material": {"n": 0.22, "k": 6.71}, "x": [0.0, 0.5]}]}],
}
LAMELLAR_ORDERS = (11, 21, 41, 81, 161, 321)
LAMELLAR_REFERENCE_ORDERS = 801
GOLD2D_ORDERS = (5, 7, 9, 11, 13, 15)


@dataclass(frozen=True)
class ConvergencePoint:
    rule: str
    orders: int
    value: float
    error: float | None
    seconds: float


def metal_grating() -> Structure:
    return Structure.from_dict(METAL_GRATING, source="<Granet & Guizal 1996 grating>")


def lamellar_tm_study(
    orders=LAMELLAR_ORDERS, rules=("li", "laurent"), reference_orders=LAMELLAR_REFERENCE_ORDERS
) -> list[ConvergencePoint]:
    """Error of the Littrow order's TM efficiency against a Li-rule reference."""
    s = metal_grating()
    reference = rcwa.solve(s, 1000.0, 30.0, 0.0, reference_orders, "p", "li").order(1).R
    points = []
    for rule in rules:
        for n in orders:
            start = time.perf_counter()
            value = rcwa.solve(s, 1000.0, 30.0, 0.0, n, "p", rule).order(1).R
            points.append(ConvergencePoint(rule, n, value, abs(value - reference), time.perf_counter() - start))
    return points


def orders_to_reach(points: list[ConvergencePoint], rule: str, error: float) -> int | None:
    """Fewest retained harmonics at which ``rule`` is (and stays) within ``error``."""
    mine = sorted((p for p in points if p.rule == rule), key=lambda p: p.orders)
    for i, p in enumerate(mine):
        if all(q.error is not None and q.error < error for q in mine[i:]):
            return p.orders
    return None


def gold2d_study(orders=GOLD2D_ORDERS, rules=("li", "nv", "laurent")) -> list[ConvergencePoint]:
    s = rcwa.load_structure("gold2d")
    points = []
    for rule in rules:
        for n in orders:
            start = time.perf_counter()
            value = rcwa.solve(s, 550.0, 0.0, 0.0, (n, n), "s", rule).order(0, 0).T
            points.append(ConvergencePoint(rule, n, value, None, time.perf_counter() - start))
    return points

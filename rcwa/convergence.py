"""Convergence of efficiencies with the number of retained harmonics, per factorization rule.

``make bench`` prints the curves (benchmarks/bench_convergence.py):

* a metallic lamellar grating in TM (the structure of [Li 1993] / [Granet 1996, Table 1]:
  index 0.22 + 6.71i, period = wavelength = 1 um, 30 deg, ridge width 0.5 um, depth
  0.1 um), where Li's inverse rule converges far faster than the Laurent rule
  ([Li 1996, Fig. 3]; [Lalanne 1996]);
* the paper's 2D gold block (built-in ``gold2d``): zero-order transmission at 550 nm,
  normal incidence, for the [Li 1997], normal-vector and Laurent rules;
* the accuracy-versus-time curve of a 2D cell (``accuracy_versus_time``, in ``workbench
  study rcwa`` for 2D structures): the error of every truncation N x N against the
  extrapolated limit (rcwa.extrapolation) versus seconds per solve and per table.
  Converged values of gold2d with error bars: rcwa.gold2d_converged.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

import rcwa
from rcwa.extrapolation import Extrapolation, extrapolate
from rcwa.solve_cache import ASR_RULES, Direction, RawSolve, SolveCache
from rcwa.structure import Structure
from rcwa.table.settings import settings_for

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


# ---------------------------------------------------------------- 2D: accuracy versus time

CURVE_QUANTITIES = ("T_total", "T00", "R_total")
CURVE_POLARIZATIONS = ("s", "p")
MAX_CACHED_ORDERS = 101  # reference_orders looks this far for cached higher truncations
ASR_MAX_ORDERS = 35  # rcwa.asr's dense 2 N^2 eigenproblem: about a minute at 35 x 35 (loaded 2-core machine)
MIN_CURVE_ORDERS = 23  # 9..23: four truncations in each parity class of (N - 1) / 2, the fewest extrapolate takes


@dataclass(frozen=True)
class CurveConfig:
    """The accuracy-versus-time curve of a 2D cell (``accuracy_versus_time``)."""

    directions: tuple[Direction, ...] = (Direction(550.0, 0.0), Direction(550.0, 30.0))
    # asr, asr_nv: Li's and the NV rule in adaptive spatial resolution's stretched coordinates (rcwa.asr;
    # cells of rectangles only)
    rules: tuple[str, ...] = ("li", "nv", "asr", "asr_nv")
    min_orders: int = 9
    max_orders: int = 25
    # A table's solves mostly see no mirror: its cost per node is timed at a general direction, up to
    # max_timed_orders, and beyond that extrapolated by a power law in N fitted to the timed ones.
    timing_direction: Direction = Direction(550.0, 30.0, 20.0)
    max_timed_orders: int = 21
    tail: int = 6
    preset: str = "paper"

    def orders(self, rule: str | None = None) -> tuple[int, ...]:
        """The curve's truncations (for the ASR rules, a dense solver without mirror sectors, up to ASR_MAX_ORDERS)."""
        top = min(self.max_orders, ASR_MAX_ORDERS) if rule in ASR_RULES else self.max_orders
        return tuple(range(self.min_orders, top + 1, 2))


def _values(raw: RawSolve) -> dict[str, float]:
    """Every (quantity, polarization) of one raw solve, by ``"quantity/pol"``."""
    out = {}
    for i, pol in enumerate(CURVE_POLARIZATIONS):
        out[f"T_total/{pol}"] = raw.T_total[i]
        out[f"R_total/{pol}"] = raw.R_total[i]
        out[f"T00/{pol}"] = raw.efficiency("T", 0, 0, i)
    return out


def reference_orders(cache: SolveCache, direction: Direction, rule: str, cfg: CurveConfig) -> tuple[int, ...]:
    """cfg.orders() and every higher odd truncation the cache already holds for ``direction`` and ``rule``
    (a converged-value run's, rcwa.gold2d_converged): the limit is extrapolated from all of them."""
    higher = (n for n in range(cfg.max_orders + 2, MAX_CACHED_ORDERS + 1, 2) if cache.get(direction, n, rule) is not None)
    return cfg.orders(rule) + tuple(higher)


def references(cache: SolveCache, cfg: CurveConfig, bar: Any = None) -> dict[str, dict[str, Extrapolation]]:
    """Per direction and rule, every quantity extrapolated over reference_orders (solving what the cache lacks)."""
    tick = bar.update if bar is not None else (lambda n=1: None)
    out: dict[str, dict[str, Extrapolation]] = {}
    for d in cfg.directions:
        for rule in cfg.rules:
            orders, solves = reference_orders(cache, d, rule, cfg), []
            for n in orders:
                solves.append(_values(cache.solve(d, n, rule)))
                tick(1 if n <= cfg.max_orders else 0)
            out[f"{d.key()}/{rule}"] = {k: extrapolate(orders, [s[k] for s in solves], tail=cfg.tail) for k in solves[0]}
    return out


def best_references(refs: dict[str, dict[str, Extrapolation]], cfg: CurveConfig) -> dict[str, Extrapolation]:
    """Per direction and quantity, the rules' extrapolation with the smallest error bar (the best estimate of the limit)."""
    best = {}
    for d in cfg.directions:
        for k in refs[f"{d.key()}/{cfg.rules[0]}"]:
            best[f"{d.key()}/{k}"] = min((refs[f"{d.key()}/{r}"][k] for r in cfg.rules), key=lambda e: e.error)
    return best


def table_nodes(structure: Structure, orders: int, preset: str) -> int:
    """Directions x wavelengths of a ``preset`` table of ``structure`` at ``orders`` x ``orders`` (symmetry folded)."""
    s = settings_for(structure, preset, orders=(orders, orders))
    return len(s.wavelengths_nm) * len(s.theta_deg) * len(s.phi_deg)


def general_solve_seconds(cache: SolveCache, cfg: CurveConfig, rule: str) -> dict[int, tuple[float, bool]]:
    """Seconds of one solve at cfg.timing_direction per truncation, and whether it was estimated (a power law
    in N fitted to the timed truncations, log-log least squares) rather than timed."""
    timed = {n: float(cache.solve(cfg.timing_direction, n, rule, warm=True).warm_seconds)  # type: ignore[arg-type]
             for n in cfg.orders(rule) if n <= cfg.max_timed_orders}
    out = {n: (t, False) for n, t in timed.items()}
    if len(timed) >= 2:
        n_t, t_t = np.array(list(timed)), np.array(list(timed.values()))
        slope, offset = np.polyfit(np.log(n_t[-3:]), np.log(t_t[-3:]), 1)
        out.update({n: (float(np.exp(offset + slope * np.log(n))), True) for n in cfg.orders(rule) if n not in timed})
    return out


def accuracy_versus_time(structure: Structure, cache: SolveCache, cfg: CurveConfig = CurveConfig(),
                         bar: Any = None) -> dict[str, Any]:
    """Error against the extrapolated limit versus seconds per solve and per table, for each rule and truncation.

    The error of a truncation is the largest |value - limit| over cfg's directions, s and p,
    and T_total, T(0,0), R_total; the limit of each is the rules' extrapolation with the
    smallest error bar (``best_references``), whose bar (``reference_error``) is the floor
    below which the curve's errors are not resolved.
    """
    refs = references(cache, cfg, bar)
    best = best_references(refs, cfg)
    rows = []
    for rule in cfg.rules:
        table = general_solve_seconds(cache, cfg, rule)
        for n in cfg.orders(rule):
            errors: dict[str, float] = {}
            seconds = []
            for d in cfg.directions:
                raw = cache.solve(d, n, rule)
                seconds.append(raw.seconds)
                for k, v in _values(raw).items():
                    errors[k] = max(errors.get(k, 0.0), abs(v - best[f"{d.key()}/{k}"].value))
            general, estimated = table.get(n, (math.nan, True))
            rows.append({"rule": rule, "orders": n, "max_error": max(errors.values()),
                         **{f"error_{q}": max(e for k, e in errors.items() if k.startswith(q + "/")) for q in CURVE_QUANTITIES},
                         "seconds_per_solve": float(np.mean(seconds)), "seconds_general_solve": general,
                         "seconds_per_table": general * table_nodes(structure, n, cfg.preset),
                         "table_seconds_estimated": estimated})
    limits = [{"direction": key.rsplit("/", 2)[0], "quantity": key.rsplit("/", 2)[1], "pol": key.rsplit("/", 2)[2],
               "value": e.value, "error": e.error} for key, e in best.items()]
    floors = {q: max(e.error for k, e in best.items() if k.rsplit("/", 2)[1] == q) for q in CURVE_QUANTITIES}
    return {"rows": rows, "limits": limits, "reference_error": max(floors.values()), "reference_errors": floors}

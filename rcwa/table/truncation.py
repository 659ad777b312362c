"""A table's own truncation error: at a few sampled nodes of each wavelength, the same
solve at a lower truncation (and, for a 2D cell, with the other factorization rule), and
the largest difference in the kept orders' efficiencies.

Why a difference of two truncations estimates the error: RCWA efficiencies converge
algebraically in the retained orders N, ``eta(N) - eta(inf) ~ C N^-p`` ([Li 1996,
Sec. 5]; [Lalanne 1996, Figs. 1-3]). With the lower truncation about N/2,
``eta(N/2) - eta(N) = C N^-p (2^p - 1)``, which is at least the error of ``eta(N)`` for
any p >= 1 (and equals it for p = 1, the slowest rate of a metallic grating under Li's
rule in TM, [Li 1996, Fig. 3]), and costs (1/2)^3 of a solve at N. Where convergence is
not monotone it is the error's size, not a bound: the metal lamellar grating of [Li 1993]
in TM (tests/rcwa/test_table_truncation.py) at 81 orders differs from 41 by 1.8e-3 and
from 401 by 2.2e-3; a dielectric grating's estimate bounds its error (the same test).
For a 2D cell, Li's rule [Li 1997] and the normal-vector method [Schuster 2007] converge
to the same limit from different sides, so their difference at the table's truncation is
a second, independent bound (rcwa.factorization); the issue's gold block is where the
two disagree most (issue 29).

Which nodes: ``sample_count`` of them per wavelength (at most one per
``NODES_PER_SAMPLE`` nodes, 1 to ``SAMPLE_NODES``), stratified over the table's
(theta, phi) nodes in theta-major order and shifted from one wavelength to the next by the
golden ratio, so the wavelengths together cover the grid; deterministic, so a resumed
build samples what an uninterrupted one does. A planned table (rcwa.table.NodePlan)
samples only nodes solved with its retained orders.

The sampled nodes of a wavelength are solved together, in one sweep per truncation and
rule (rcwa.table.compute.solve_directions, the table's own code; one sweep builds a
layer's Fourier matrices once, which for the normal-vector method costs more than the
solves), so a record can be recomputed exactly; the values compared are those a table
stores (float32, its polarizations, its arrays, both sides),
so differences below about 1e-7 are float32 rounding.
"""

from __future__ import annotations

import math
import time

import numpy as np

from rcwa.factorization import resolve_rule
from rcwa.structure import Structure
from rcwa.table.compute import clamped, solve_directions
from rcwa.table.settings import TableSettings, kept_indices, pol_names

SAMPLE_NODES = 8       # nodes sampled per wavelength, at most
NODES_PER_SAMPLE = 30  # at most one sampled node per this many nodes of a wavelength
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
OTHER_RULE = {"li": "nv", "nv": "li", "laurent": "li"}


def lower_orders(orders: tuple[int, ...], keep: tuple[int, ...]) -> tuple[int, ...] | None:
    """The lower truncation: about half the retained orders (odd), at least the kept ones;
    None when the table retains no more than it keeps (no lower truncation holds the kept
    orders)."""
    lower = tuple(max(k, (n // 2) | 1) for n, k in zip(orders, keep, strict=True))
    return None if lower == tuple(orders) else lower


def sample_count(nodes: int) -> int:
    """Sampled nodes of a wavelength with ``nodes`` candidate nodes (0 when there are none)."""
    return 0 if nodes == 0 else min(SAMPLE_NODES, max(1, nodes // NODES_PER_SAMPLE))


def sample_nodes(settings: TableSettings, index: int, mask: np.ndarray | None = None) -> list[tuple[int, int]]:
    """(theta index, phi index) of the nodes sampled at wavelength ``index`` (module docstring)."""
    shape = (len(settings.theta_deg), len(settings.phi_deg))
    exact = np.ones(shape, bool) if mask is None else np.asarray(mask, bool)
    candidates = np.flatnonzero(exact.ravel())  # theta-major
    count = sample_count(candidates.size)
    if count == 0:
        return []
    stride = candidates.size / count
    shift = (index * GOLDEN) % 1.0
    picks = [candidates[min(candidates.size - 1, int((j + shift) * stride))] for j in range(count)]
    return [(int(p // shape[1]), int(p % shape[1])) for p in picks]


def node_values(structure: Structure, settings: TableSettings, wavelength_nm: float, nodes: list[tuple[float, float]],
                orders: tuple[int, ...], rule: str) -> dict[str, np.ndarray]:
    """The table's arrays at the (theta, phi) ``nodes`` (degrees), solved together in one
    sweep with ``orders`` and ``rule`` (rcwa.table.compute.solve_directions): name ->
    (node, kept order, pol), float32 as stored. On one thread: a 1D sweep's eigen-solve
    refinement chains depend on the thread count (rcwa/cpp/sweep.hpp), the record must not."""
    theta = clamped([t for t, _ in nodes])
    phi = np.array([p for _, p in nodes], float)
    values, _ = solve_directions(structure, settings, wavelength_nm, theta, phi, tuple(orders), rule, 1)
    return values


def largest_difference(a: dict[str, np.ndarray], b: dict[str, np.ndarray], settings: TableSettings) -> dict:
    """The largest |a - b| over the arrays, kept orders and polarizations both hold, and where."""
    best: dict = {"max_difference": -1.0}
    kept_m, kept_n = kept_indices(settings.keep)
    pols = pol_names(settings.pol)
    for name in sorted(set(a) & set(b)):
        diff = np.abs(a[name].astype(np.float64) - b[name].astype(np.float64))
        q, p = np.unravel_index(int(np.argmax(diff)), diff.shape)
        if diff[q, p] > best["max_difference"]:
            best = {"max_difference": float(diff[q, p]), "array": name, "pol": pols[p],
                    "order": [int(kept_m[q]), int(kept_n[q])]}
    return best


def _differences(a: dict[str, np.ndarray], b: dict[str, np.ndarray], nodes: list[tuple[float, float]],
                 settings: TableSettings) -> list[dict]:
    """largest_difference at each node, with the node."""
    return [{**largest_difference({k: v[i] for k, v in a.items()}, {k: v[i] for k, v in b.items()}, settings),
             "theta_deg": theta, "phi_deg": phi} for i, (theta, phi) in enumerate(nodes)]


def _worst(found: list[dict]) -> dict:
    return max(found, key=lambda d: d["max_difference"])


def estimate_truncation(structure: Structure, settings: TableSettings, index: int,
                        mask: np.ndarray | None = None) -> dict:
    """The truncation-error record of wavelength ``index`` (module docstring): the sampled
    nodes, the lower truncation's and (2D) the other rule's largest difference with the
    node and order where it occurs, and the seconds the sample took."""
    start = time.perf_counter()
    wl = float(settings.wavelengths_nm[index])
    rule = resolve_rule(settings.factorization, structure.dimension, structure.layers)
    other = OTHER_RULE[rule] if structure.dimension == 2 else None
    lower = lower_orders(settings.orders, settings.keep)
    picked = sample_nodes(settings, index, mask)
    nodes = [(float(settings.theta_deg[j]), float(settings.phi_deg[k])) for j, k in picked]
    by_order: list[dict] = []
    by_rule: list[dict] = []
    if nodes:
        table = node_values(structure, settings, wl, nodes, settings.orders, rule)
        if lower is not None:
            low = node_values(structure, settings, wl, nodes, lower, rule)
            by_order = _differences(table, low, nodes, settings)
        if other is not None:
            alt = node_values(structure, settings, wl, nodes, settings.orders, other)
            by_rule = _differences(table, alt, nodes, settings)
    record: dict = {"wavelength_nm": wl, "orders": list(settings.orders), "rule": rule,
                    "nodes": [list(node) for node in nodes]}
    if not nodes:
        record["reason"] = "no node of this wavelength is solved with the table's orders"
    if lower is None:
        record["truncation"] = None
        record["truncation_reason"] = "the table retains only its kept orders: no lower truncation holds them"
    elif by_order:
        record["truncation"] = {"lower_orders": list(lower), **_worst(by_order)}
    if by_rule:
        record["factorization"] = {"other_rule": other, **_worst(by_rule)}
    record["seconds"] = round(time.perf_counter() - start, 4)
    return record


def summary(meta: dict, progress: dict | None = None) -> dict | None:
    """What a table records of its truncation error (``truncation_error`` in its metadata;
    for an unfinished build, the finished chunks' records in progress.json): per wavelength
    the records, overall the largest differences and the sample's share of the build time.
    None for a table written before tables recorded it."""
    recorded = meta.get("truncation_error")
    if recorded is None and progress:
        recorded = {i: r["truncation"] for i, r in progress.items() if "truncation" in r} or None
    if recorded is None:
        return None
    count = len(meta["settings"]["wavelengths_nm"])
    per = [recorded.get(str(i)) for i in range(count)]
    have = [r for r in per if r is not None]
    out: dict = {"wavelengths": per, "wavelengths_nm": list(meta["settings"]["wavelengths_nm"]),
                 "wavelengths_recorded": len(have), "wavelengths_total": count}
    for key in ("truncation", "factorization"):
        worst = [dict(r[key], wavelength_nm=r["wavelength_nm"]) for r in have if r.get(key)]
        out[key] = _worst(worst) if worst else None
    chunk_seconds = meta.get("chunk_seconds") or {i: r["seconds"] for i, r in (progress or {}).items()}
    sample_seconds = sum(r["seconds"] for r in have)
    build_seconds = sum(chunk_seconds.get(str(i), 0.0) for i, r in enumerate(per) if r is not None)
    out["sample_seconds"] = sample_seconds
    out["sample_share"] = sample_seconds / build_seconds if build_seconds > 0 else None
    return out


def format_summary(info: dict | None) -> list[str]:
    """Lines for ``workbench rcwa info``: the largest differences and, per wavelength, both."""
    if info is None:
        return ["  truncation    error not recorded (a table written before tables recorded it)"]
    lines = [f"  truncation    error recorded at {info['wavelengths_recorded']} of {info['wavelengths_total']} "
             f"wavelengths (sample: {info['sample_seconds']:.2f} s"
             + (f", {info['sample_share']:.1%} of the build)" if info["sample_share"] is not None else ")")]
    for key, words in (("truncation", "lower truncation"), ("factorization", "other factorization rule")):
        worst = info[key]
        if worst is not None:
            lines.append(f"    largest vs {words}: {_where(worst)}")
    for wavelength, r in zip(info["wavelengths_nm"], info["wavelengths"], strict=True):
        if r is None:
            lines.append(f"    {wavelength:g} nm: not recorded (finished by a build from before tables recorded it)")
            continue
        parts = [f"{key_words}: {_where(r[key], at=False)}" for key, key_words in
                 (("truncation", "vs lower"), ("factorization", "vs other rule")) if r.get(key)]
        if not parts:
            parts.append(r.get("truncation_reason") or r.get("reason", "nothing sampled"))
        lines.append(f"    {r['wavelength_nm']:g} nm: " + "; ".join(parts))
    return lines


def _where(d: dict, at: bool = True) -> str:
    against = "x".join(map(str, d["lower_orders"])) if "lower_orders" in d else d["other_rule"]
    wavelength = f" at {d['wavelength_nm']:g} nm," if at else " at"
    return (f"{d['max_difference']:.2e} ({against}) in {d['array']} order ({d['order'][0]}, {d['order'][1]}) "
            f"{d['pol']}{wavelength} theta {d['theta_deg']:g}, phi {d['phi_deg']:g} deg")

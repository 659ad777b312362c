"""What an element's efficiency table costs to build on this machine, for the planner.

Measured, not modelled: a short sweep at the table's orders (rcwa.sweep), timed on
COST_SAMPLE_DIRECTIONS directions at the table's middle wavelength, then scaled to the
table's (wavelength, theta, phi) nodes and sides on this machine's cores. A planned table
(rcwa.table.NodePlan) solves the nodes the camera's rays read with the table's orders and
the others with the fill's (the kept orders only), so the same sweep at the fill's orders
gives the planned table's time and the fill's error on the sample.

The table's truncation-error sample (rcwa.table.truncation) is part of its build: at
``sample_count`` nodes of each wavelength, sweeps at the table's orders, at the lower
truncation (about N/2) and, for a 2D cell, with the other factorization rule, on one thread
after each chunk (rcwa.table.store), so its seconds are not divided among the cores. Its
time is measured by running that very sample (rcwa.table.truncation.estimate_truncation) at
the middle wavelength twice: the first run also pays what a process computes once per
build (the normal-vector method's field, cached per layer: 0.8 s for gold2d at 7 x 7
orders, far more than its sweep), the second is one wavelength's share. A sweep's time
is a per-sweep part (for the normal-vector method most of it: its Fourier matrices, the
same at 8 nodes as at 16) and a part per node, so a planned table, which samples fewer
nodes where the camera needs few, is timed once more at its own typical count and the
per-wavelength time taken linear in the count between the two measurements.
"""

from __future__ import annotations

import os
import time
from collections import Counter
from dataclasses import dataclass

import numpy as np

from rcwa.factorization import resolve_rule
from rcwa.structure import Structure
from rcwa.sweep import sweep_directions
from rcwa.table import TableSettings, pol_names
from rcwa.table.truncation import OTHER_RULE, estimate_truncation, lower_orders, sample_count

COST_SAMPLE_DIRECTIONS = 16  # directions timed for the cost model
FLOAT32_BYTES = 4  # the tables' efficiencies are float32 (rcwa.table)


@dataclass(frozen=True)
class TruncationCost:
    """The truncation-error sample's estimated seconds (module docstring; 0 when not
    measured), and what it solves: sampled nodes over all wavelengths, whole and planned,
    the lower truncation (None: the table retains only its kept orders) and the other rule
    (None in 1D)."""

    seconds_whole: float
    seconds_planned: float
    nodes_whole: int
    nodes_planned: int
    lower_orders: tuple[int, ...] | None
    other_rule: str | None


@dataclass(frozen=True)
class TableCost:
    """An element's estimated table cost on this machine's cores (seconds, megabytes); the
    seconds include the truncation-error sample (``truncation``)."""

    seconds_whole: float
    seconds_planned: float
    megabytes_whole: float
    fill_orders: tuple[int, ...]  # the orders retained at the nodes no camera ray reads
    fill_error: dict[str, float]  # |R_fill - R| over the cost sample: max, median ({} when not measured)
    truncation: TruncationCost


def table_cost(structure: Structure, settings: TableSettings, see_through: bool, kept_orders: int,
               masks: dict[str, np.ndarray], measure: bool) -> TableCost:
    """The whole table's and the planned table's estimated seconds (measured per direction
    here when ``measure``, else 0), and the whole table's size. ``masks``: the nodes the
    camera's rays read per table (R, T, R_below, T_below; wavelength, theta, phi); the node
    counts include the wavelength axis."""
    nodes_whole = len(settings.theta_deg) * len(settings.phi_deg) * len(settings.wavelengths_nm)
    whole_tables = ["R", "T"] if see_through else ["R"]
    if settings.both_sides or see_through:
        whole_tables += [name + "_below" for name in whole_tables]
    fill_orders = tuple(settings.keep)  # the nodes no camera ray reads: only the kept orders retained (rcwa.table.NodePlan)
    per_dir, per_fill, fill_error = (cost_sample(structure, settings, fill_orders) if measure else (0.0, 0.0, {}))
    cores = os.cpu_count() or 1
    sides_whole = 2 if (settings.both_sides or see_through) else 1
    needed_above = int((masks["R"] | masks["T"]).sum())
    needed_below = int((masks["R_below"] | masks["T_below"]).sum())
    union = masks["R"] | masks["T"] | masks["R_below"] | masks["T_below"]  # the planned table's exact nodes
    truncation = truncation_cost(structure, settings, sides_whole, union, measure)
    bytes_whole = len(whole_tables) * nodes_whole * kept_orders * len(pol_names(settings.pol)) * FLOAT32_BYTES
    return TableCost(seconds_whole=per_dir * nodes_whole * sides_whole / cores + truncation.seconds_whole,
                     seconds_planned=(per_dir * (needed_above + needed_below)
                                      + per_fill * (nodes_whole * sides_whole - needed_above - needed_below)) / cores
                     + truncation.seconds_planned,
                     megabytes_whole=bytes_whole / 1e6, fill_orders=fill_orders, fill_error=fill_error,
                     truncation=truncation)


def cost_sample(structure: Structure, settings: TableSettings,
                fill_orders: tuple[int, ...]) -> tuple[float, float, dict[str, float]]:
    """Measured on COST_SAMPLE_DIRECTIONS directions at the middle wavelength: seconds per
    direction with the table's orders and with the fill's, and the fill's error there
    (|R_fill - R| over the kept orders: max and median)."""
    wl = settings.wavelengths_nm[len(settings.wavelengths_nm) // 2]
    rng = np.random.default_rng(0)
    theta = rng.uniform(0.0, 80.0, COST_SAMPLE_DIRECTIONS)
    phi = rng.uniform(0.0, 90.0, COST_SAMPLE_DIRECTIONS)
    sweep_directions(structure, wl, theta[:2], phi[:2], settings.orders, settings.keep, threads=1)  # warm up
    start = time.perf_counter()
    exact = sweep_directions(structure, wl, theta, phi, settings.orders, settings.keep, threads=1)
    middle = time.perf_counter()
    fill = sweep_directions(structure, wl, theta, phi, fill_orders, settings.keep, threads=1)
    end = time.perf_counter()
    error = np.abs(fill.R - exact.R)
    return ((middle - start) / COST_SAMPLE_DIRECTIONS, (end - middle) / COST_SAMPLE_DIRECTIONS,
            {"max": float(error.max()), "median": float(np.median(error.max(axis=(1, 2))))})


def truncation_counts(settings: TableSettings, exact: np.ndarray | None) -> list[int]:
    """Nodes the truncation-error sample solves at each wavelength (rcwa.table.truncation.sample_count):
    of the whole table (``exact`` None) or of a planned table with these exact nodes (wavelength, theta, phi)."""
    per_wavelength = len(settings.theta_deg) * len(settings.phi_deg)
    if exact is None:
        return [sample_count(per_wavelength)] * len(settings.wavelengths_nm)
    return [sample_count(int(np.count_nonzero(exact[i]))) for i in range(len(settings.wavelengths_nm))]


def truncation_cost(structure: Structure, settings: TableSettings, sides: int, exact: np.ndarray,
                    measure: bool) -> TruncationCost:
    """The truncation-error sample's seconds for the whole table and for the planned one
    (``exact``: its exact nodes), for ``sides`` sides (module docstring)."""
    whole, planned = truncation_counts(settings, None), truncation_counts(settings, exact)
    rule = resolve_rule(settings.factorization, structure.dimension, structure.layers)
    other = OTHER_RULE[rule] if structure.dimension == 2 else None
    seconds_whole = seconds_planned = 0.0
    if measure and whole[0]:
        # the sample solves one side per settings.both_sides; the render's build has ``sides``
        scale = sides / (2 if settings.both_sides else 1)
        once, per_wavelength = _timed_sample(structure, settings, exact, whole, planned)
        seconds_whole = once + scale * sum(per_wavelength(k) for k in whole)  # once: for both sides (cached per layer)
        seconds_planned = once + scale * sum(per_wavelength(k) for k in planned) if any(planned) else 0.0
    return TruncationCost(seconds_whole, seconds_planned, sum(whole), sum(planned),
                          lower_orders(settings.orders, settings.keep), other)


def _timed_sample(structure: Structure, settings: TableSettings, exact: np.ndarray, whole: list[int],
                  planned: list[int]):
    """The sample's once-per-build seconds and its seconds at a wavelength as a function of
    its node count (module docstring): run at the middle wavelength twice and, where the
    planned table samples a different typical count, once at such a wavelength."""
    middle = len(settings.wavelengths_nm) // 2
    cold = estimate_truncation(structure, settings, middle)["seconds"]
    warm = estimate_truncation(structure, settings, middle)["seconds"]
    typical = Counter(k for k in planned if k).most_common(1)
    slope = warm / whole[0]
    if typical and typical[0][0] != whole[0]:
        index = planned.index(typical[0][0])
        seconds = estimate_truncation(structure, settings, index, exact[index])["seconds"]
        slope = max(0.0, (warm - seconds) / (whole[0] - typical[0][0]))
    return max(0.0, cold - warm), lambda k: 0.0 if k == 0 else max(0.0, warm + slope * (k - whole[0]))


def truncation_text(cost: dict, seconds_whole: float) -> str:
    """The plan's line for the truncation-error sample (``cost``: a TruncationCost as a dict;
    ``seconds_whole``: the whole table's estimated seconds, the sample's included)."""
    if not cost:
        return "  truncation    not estimated"
    if not cost["nodes_whole"]:
        return "  truncation    no node to sample: the table's error is not estimated"
    against = [f"at {'x'.join(map(str, cost['lower_orders']))} orders" if cost["lower_orders"] else "",
               f"with the {cost['other_rule']} rule" if cost["other_rule"] else ""]
    words = " and ".join(a for a in against if a) or "with nothing to compare (the table retains only its kept orders)"
    share = f" ({cost['seconds_whole'] / seconds_whole:.0%})" if seconds_whole > 0 else ""
    return (f"  truncation    error sampled at {cost['nodes_whole']} nodes ({cost['nodes_planned']} planned), solved "
            f"again {words} on one thread: ~{_seconds(cost['seconds_whole'])} s{share} of the whole table, "
            f"~{_seconds(cost['seconds_planned'])} s of the planned (included above)")


def _seconds(value: float) -> str:
    """Whole seconds from 10 s up, two significant digits below (a draft's sample takes a fraction of one)."""
    return f"{value:.0f}" if value >= 10 else f"{value:.2g}"

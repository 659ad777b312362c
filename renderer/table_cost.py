"""What an element's efficiency table costs to build on this machine, for the planner.

Measured, not modelled: a short sweep at the table's orders (rcwa.sweep), timed on
COST_SAMPLE_DIRECTIONS directions at the table's middle wavelength, then scaled to the
table's (wavelength, theta, phi) nodes and sides on this machine's cores. A planned table
(rcwa.table.NodePlan) solves the nodes the camera's rays read with the table's orders and
the others with the fill's (the kept orders only), so the same sweep at the fill's orders
gives the planned table's time and the fill's error on the sample.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import numpy as np

from rcwa.structure import Structure
from rcwa.sweep import sweep_directions
from rcwa.table import TableSettings, pol_names

COST_SAMPLE_DIRECTIONS = 16  # directions timed for the cost model
FLOAT32_BYTES = 4  # the tables' efficiencies are float32 (rcwa.table)


@dataclass(frozen=True)
class TableCost:
    """An element's estimated table cost on this machine's cores (seconds, megabytes)."""

    seconds_whole: float
    seconds_planned: float
    megabytes_whole: float
    fill_orders: tuple[int, ...]  # the orders retained at the nodes no camera ray reads
    fill_error: dict[str, float]  # |R_fill - R| over the cost sample: max, median ({} when not measured)


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
    bytes_whole = len(whole_tables) * nodes_whole * kept_orders * len(pol_names(settings.pol)) * FLOAT32_BYTES
    return TableCost(seconds_whole=per_dir * nodes_whole * sides_whole / cores,
                     seconds_planned=(per_dir * (needed_above + needed_below)
                                      + per_fill * (nodes_whole * sides_whole - needed_above - needed_below)) / cores,
                     megabytes_whole=bytes_whole / 1e6, fill_orders=fill_orders, fill_error=fill_error)


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

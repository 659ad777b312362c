"""Efficiency tables: the renderer's input, built by sweeps, stored chunked on disk.

A table holds, for the kept orders of a structure, the diffraction efficiencies over a
grid of wavelength x polar angle x azimuth of the incident light (rcwa conventions:
(theta, phi) of the incident tangential wave vector), for reflection and, where the
substrate lets light through, transmission; optionally also for light from below (the
z-inverted structure, [Lange 2021, Sec. 2.2], for see-through elements).

One job per module:

* ``settings``: what a table holds (TableSettings, presets, NodePlan of a planned table)
  and the request's content key;
* ``compute``: one chunk (one wavelength) of efficiencies, by rcwa.sweep;
* ``store``: the zarr store on disk, built, resumed and repaired under the table's lock
  (build_table);
* ``reader``: a finished table opened and verified (open_table, Table);
* ``truncation``: the table's own truncation error, sampled per wavelength
  (estimate_truncation; truncation_summary, what ``workbench rcwa info`` prints).
"""

from rcwa.table.compute import compute_chunk, flipped
from rcwa.table.reader import Table, open_table, read_table_metadata
from rcwa.table.settings import (
    FORMAT_VERSION,
    GRAZING_THETA_DEG,
    POLARIZATIONS,
    PRESETS,
    NodePlan,
    TableSettings,
    angle_grid,
    check_materials,
    kept_indices,
    parse_wavelengths,
    planned,
    pol_names,
    request_key,
    settings_for,
    symmetry_for,
    table_symmetry,
    transmits,
)
from rcwa.table.store import ARRAY_NAMES, PLANNED_NODES, TABLE_FILES, BuildReport, build_table
from rcwa.table.truncation import estimate_truncation, format_summary, lower_orders, sample_nodes
from rcwa.table.truncation import summary as truncation_summary

__all__ = [
    "ARRAY_NAMES", "FORMAT_VERSION", "GRAZING_THETA_DEG", "PLANNED_NODES", "POLARIZATIONS", "PRESETS", "TABLE_FILES",
    "BuildReport", "NodePlan", "Table", "TableSettings", "angle_grid", "build_table", "check_materials",
    "compute_chunk", "estimate_truncation", "flipped", "format_summary", "kept_indices", "lower_orders", "open_table",
    "parse_wavelengths", "planned", "pol_names", "read_table_metadata", "request_key", "sample_nodes", "settings_for",
    "symmetry_for", "table_symmetry", "transmits", "truncation_summary",
]

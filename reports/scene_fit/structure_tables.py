"""Efficiencies for fitted structure fields (the CD's groove depth and width): RCWA tables on a
grid of their values, read as one efficiency multilinear in them between neighbouring nodes.

The forward model (reports.scene_fit.model) weights every lit (pixel, wavelength) by the
order's efficiency (renderer.trace.efficiency_weights); a groove's depth (a layer's thickness)
or width (a stripe's width) changes those efficiencies, not the directions. Re-solving at
every evaluation would cost a table per step, so tables are built once on a grid across the
fields' bounds: ``NODES_ONE_FIELD`` values of one field, or ``NODES_TWO_FIELDS`` of each of
two (their product), each with the scene's own table settings (renderer.tables; the user's
cache keeps them by content, so a second fit reuses them), and the efficiency at a point is
the multilinear blend of the 2^d nodes around it. The nodes are close enough for that:
across the default bounds (+-30 % of 0.11 um, rcwa.structures' cd) neighbouring depth nodes
differ in phase depth 4 pi n d / lambda by about 0.4 rad at 500 nm; neighbouring width
nodes (+-30 % of 0.6 um) move the stripe's edges by 0.03 um, 2 % of the 1.6 um period. Each
table is planned for the fit's cameras (fit_nodes: the nodes they read, grown by
``NODE_MARGIN``, solved with all the table's orders, the others with the kept orders only):
61 % of a paper table's nodes for cornell_cd's camera, 85 % of a draft table's (whose grid is
coarse: no saving there). What it costs is recorded (``seconds``: 7 draft tables in 10.8 s on
2 cores, 25 for depth and width together 46 s while another job shared the cores; the paper preset's about 2 minutes each
whole).
"""

from __future__ import annotations

import dataclasses
import itertools
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
import tomli_w

from rcwa.structure import load_structure
from rcwa.table.settings import NodePlan
from renderer.fit_parameters import FitParameter
from renderer.trace.efficiency_weights import Efficiency, scene_efficiency
from renderer.trace.planner import planned_nodes
from reports.scene_fit.apply import structure_data_with

NODES_ONE_FIELD = 7
NODES_TWO_FIELDS = 5
STRUCTURE_KINDS = ("thickness", "width")  # the fit kinds whose efficiencies these tables give
NODE_MARGIN = 2  # grid nodes added about each camera's planned nodes (fit_nodes)


class BlendedEfficiency:
    """sum_k w_k eta_k of efficiencies (the same call as renderer.trace.efficiency_weights.Efficiency)."""

    def __init__(self, parts: list[tuple[float, Efficiency]]):
        self.parts = [(w, e) for w, e in parts if w > 0.0] or parts[:1]
        self.source = " + ".join(f"{w:.3f} x {e.source}" for w, e in self.parts)

    def __call__(self, m: int, wavelengths_nm: np.ndarray, sin_air: np.ndarray, phi_deg: np.ndarray) -> np.ndarray:
        out = np.zeros(len(wavelengths_nm))
        for w, e in self.parts:
            out = out + w * e(m, wavelengths_nm, sin_air, phi_deg)
        return out


def field_name(p: FitParameter) -> str:
    """The structure field a parameter fits (reports.scene_fit.apply.structure_data_with's keys)."""
    return f"layers[{p.layer or 0}].thickness" if p.kind == "thickness" else f"layers[{p.layer}].shapes[{p.shape}].width"


def _structure_with(reference: str, changes: dict[str, float], folder: Path, tag: str) -> Path:
    data = structure_data_with(tomllib.loads(load_structure(reference).text), changes)
    data["name"] = f"{data.get('name', 'structure')}_{tag}"
    path = folder / f"{data['name']}.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def fit_nodes(spec, cameras: list, index: int = 0) -> NodePlan | None:
    """The table nodes the fit's cameras read of CD ``index`` (renderer.trace.planner.planned_nodes for
    each camera, grown by ``NODE_MARGIN`` grid nodes, so the fit's moves of the CD and the light
    stay on solved nodes; their union): the depth's and width's tables solve only those with all
    their orders [the planner's node mask], the others with the kept orders. None without cameras."""
    masks, fill = [], None
    for camera in cameras:
        nodes = planned_nodes(dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, model=camera)),
                              NODE_MARGIN).get(f"cd[{index}]")
        if nodes is not None:
            masks.append(nodes.mask)
            fill = nodes.fill_orders
    if not masks or fill is None:
        return None
    return NodePlan(np.logical_or.reduce(masks), fill)


class StructureEfficiencies:
    """The CD's efficiencies on a grid of one or two structure fields across ``parameters``' bounds,
    planned for ``cameras`` (fit_nodes; whole tables without)."""

    def __init__(self, spec, parameters: list[FitParameter], cameras: list | None = None):
        started = time.perf_counter()
        if not 1 <= len(parameters) <= 2:
            raise ValueError("one or two structure fields")
        self.fields = [field_name(p) for p in parameters]
        count = NODES_ONE_FIELD if len(parameters) == 1 else NODES_TWO_FIELDS
        self.axes = [np.linspace(p.lower[0], p.upper[0], count) for p in parameters]
        index = parameters[0].cd_index or 0
        cd = spec.cds[index]
        nodes = fit_nodes(spec, cameras or [], index)
        self.planned_share = None if nodes is None else float(nodes.mask.mean())
        self.efficiencies: dict[tuple[int, ...], Efficiency] = {}
        with tempfile.TemporaryDirectory() as tmp:  # the copies only name the tables, which the cache keeps
            for at in itertools.product(*(range(len(a)) for a in self.axes)):
                changes = {f: float(a[i]) for f, a, i in zip(self.fields, self.axes, at, strict=True)}
                tag = "_".join(f"{chr(ord('a') + k)}{v:.5f}" for k, v in enumerate(changes.values()))
                path = _structure_with(cd.structure, changes, Path(tmp), tag)
                cds = list(spec.cds)
                cds[index] = dataclasses.replace(cd, structure=str(path))
                self.efficiencies[at] = scene_efficiency(dataclasses.replace(spec, cds=tuple(cds)), index, nodes)
        self.seconds = time.perf_counter() - started

    def at(self, values: dict[str, float]) -> BlendedEfficiency:
        """The efficiency at the fields' ``values`` ({field: um}), multilinear between the nodes."""
        cells = []
        for field, axis in zip(self.fields, self.axes, strict=True):
            i = int(np.clip(np.searchsorted(axis, values[field]) - 1, 0, len(axis) - 2))
            w = float(np.clip((values[field] - axis[i]) / (axis[i + 1] - axis[i]), 0.0, 1.0))
            cells.append(((i, 1.0 - w), (i + 1, w)))
        parts = []
        for corner in itertools.product(*cells):
            weight = float(np.prod([w for _, w in corner]))
            parts.append((weight, self.efficiencies[tuple(i for i, _ in corner)]))
        return BlendedEfficiency(parts)

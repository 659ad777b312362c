"""A scene with scene-fit values applied (renderer.fit_parameters: the names and fit coordinates).

The CD's placement and the light change in the SceneSpec; a structure's fields (the
period, a layer's thickness, a stripe's width) are returned beside it, since the structure is a file the
scene names (the forward model reads the period from here; a fitted scene file gets a
structure file of its own, reports.scene_fit.outputs).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from renderer.fit_parameters import FitTable
from renderer.placement import frame_to


def tilted_normal(normal: np.ndarray, rotation_deg: float, tilt_deg: np.ndarray) -> np.ndarray:
    """The unit normal tilted by ``tilt_deg`` (toward e1, toward e2 of placement.frame_to)."""
    frame = frame_to(tuple(normal), rotation_deg)
    t = np.tan(np.radians(tilt_deg))
    n = frame[:, 2] + t[0] * frame[:, 0] + t[1] * frame[:, 1]
    return n / np.linalg.norm(n)


def tilt_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between two unit normals, in degrees."""
    return float(np.degrees(np.arccos(np.clip(float(np.dot(a, b)), -1.0, 1.0))))


@dataclass(frozen=True)
class AppliedScene:
    """A scene with fit values applied: the spec (placements and light) and, per CD, the
    structure fields that changed ({cd index: {"period": um, "layers[j].thickness": um,
    "layers[j].shapes[k].width": um}})."""

    spec: Any
    structure_changes: dict[int, dict[str, float]]

    def period_um(self, cd_index: int) -> float | None:
        return self.structure_changes.get(cd_index, {}).get("period")


def apply_values(spec: Any, table: FitTable, values: np.ndarray) -> AppliedScene:
    """``spec`` with the fit's ``values`` (fit coordinates, FitTable order) in place of the file's."""
    cds = list(spec.cds)
    light = spec.light
    changes: dict[int, dict[str, float]] = {}
    for p, x in zip(table.free, table.split(values).values(), strict=True):
        i = p.cd_index if p.cd_index is not None else 0  # a CD's parameters always name one
        if p.kind == "light.center":
            light = replace(light, center=(float(x[0]), light.center[1], float(x[1])))
        elif p.kind == "light.size":
            light = replace(light, size=(float(x[0]), float(x[1])))
        elif p.kind == "center":
            cds[i] = replace(cds[i], center=tuple(float(c) for c in x))
        elif p.kind == "normal":
            base = spec.cds[i]
            cds[i] = replace(cds[i], normal=tuple(
                tilted_normal(np.asarray(base.normal), base.rotation_deg, x).tolist()))
        elif p.kind == "period":
            changes.setdefault(i, {})["period"] = float(x[0])
        elif p.kind == "width":
            changes.setdefault(i, {})[f"layers[{p.layer}].shapes[{p.shape}].width"] = float(x[0])
        else:
            changes.setdefault(i, {})[f"layers[{p.layer}].thickness"] = float(x[0])
    return AppliedScene(replace(spec, cds=tuple(cds), light=light), changes)


_LAYER_FIELD = re.compile(r"^layers\[(\d+)\]\.(thickness|shapes\[(\d+)\]\.width)$")


def structure_data_with(data: dict, changes: dict[str, float]) -> dict:
    """A structure file's parsed TOML (rcwa.structure's format) with ``changes`` in place
    (AppliedScene.structure_changes' keys: "period", "layers[j].thickness", and
    "layers[j].shapes[k].width": the stripe's x = [c - w / 2, c + w / 2] about its centre c)."""
    for field, value in changes.items():
        if field == "period":
            data["period"] = [value]
            continue
        match = _LAYER_FIELD.match(field)
        if match is None:
            raise ValueError(f"not a structure field of the scene fit: {field!r}")
        layer = data["layers"][int(match.group(1))]
        if match.group(3) is None:
            layer["thickness"] = value
        else:
            stripe = layer["shapes"][int(match.group(3))]
            centre = 0.5 * (float(stripe["x"][0]) + float(stripe["x"][1]))
            stripe["x"] = [centre - 0.5 * value, centre + 0.5 * value]
    return data

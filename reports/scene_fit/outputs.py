"""What ``workbench fit`` writes: DIR/scene_fit.json and DIR/fitted_scene.toml.

scene_fit.json: ``parameters`` {NAME: {nominal, value, std, unit, components, ...}} in the
scene file's terms (a normal as its unit vector, with its tilt from the file's in degrees;
``std`` per fitted component, in the component's unit), ``correlations`` (between
components, FitTable.labels order), ``residuals_before_px`` and ``residuals_after_px``
({median, p95, count} of |predicted - photo| band-edge positions at the file's and the
fitted values), ``verdict`` (reports.scene_fit.verdict), ``held``, settings, versions, timings.

fitted_scene.toml: the scene file with the fitted values in place (a scene any command
accepts). A fitted structure field (the period, a layer's thickness, a stripe's width) changes the structure
file the scene names: a copy with the fitted values is written beside it
(``cd0_structure.toml``; its material CSV files named by absolute paths) and the scene
points to it by a relative path. Other paths the scene resolved are made absolute
(calibration.pose.scene_file.absolute_reference), since the file is written elsewhere.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from calibration.pose.scene_file import absolute_reference
from rcwa.structure import BUILTIN_STRUCTURES, load_structure
from renderer.fit_parameters import FitParameter, FitTable
from reports.scene_fit.apply import apply_values, structure_data_with, tilt_angle_deg
from workbench.core.files import atomic_write_text


def _file_value(p: FitParameter, spec, values: np.ndarray) -> list[float] | float:
    """The parameter's value as the scene file writes it, for fit-coordinate ``values``."""
    if p.kind in ("period", "thickness", "width"):
        return float(values[0])
    if p.kind == "center":
        return [float(v) for v in values]
    if p.kind == "light.center":
        return [float(values[0]), float(spec.light.center[1]), float(values[1])]
    if p.kind == "light.size":
        return [float(v) for v in values]
    return [float(v) for v in apply_values(spec, FitTable((p,), {}, True), values).spec.cds[p.cd_index].normal]


def parameters_json(spec, table: FitTable, nominal: np.ndarray, values: np.ndarray, std: np.ndarray) -> dict[str, Any]:
    """scene_fit.json's ``parameters``."""
    out: dict[str, Any] = {}
    at = 0
    for p in table.free:
        sl = slice(at, at + p.size)
        at += p.size
        entry: dict[str, Any] = {"nominal": _file_value(p, spec, nominal[sl]), "value": _file_value(p, spec, values[sl]),
                                 "std": [float(s) for s in std[sl]] if p.size > 1 else float(std[sl][0]),
                                 "unit": p.unit, "components": list(p.components),
                                 "bounds": [list(p.lower), list(p.upper)]}
        if p.kind == "normal":
            entry["unit"] = "unit vector; std in deg of tilt toward e1, e2"
            entry["tilt_deg"] = tilt_angle_deg(np.asarray(entry["nominal"]), np.asarray(entry["value"]))
            entry["tilt_std_deg"] = float(np.hypot(*std[sl]))
        if p.prior_std is not None:
            entry["prior_std"] = list(p.prior_std)
        out[p.name] = entry
    return out


def _material_specs(data: dict) -> list[dict]:
    """The structure data's ``{ file = ... }`` material tables (superstrate, substrate, layers, shapes)."""
    values = [data.get("superstrate"), data.get("substrate")]
    for layer in data.get("layers", []):
        values += [layer.get("material")] + [shape.get("material") for shape in layer.get("shapes", [])]
    return [v for v in values if isinstance(v, dict) and isinstance(v.get("file"), str)]


def _structure_copy(reference: str, changes: dict[str, float], path: Path) -> str:
    """A copy of the structure file ``reference`` with ``changes`` (reports.scene_fit.apply.structure_data_with) at ``path``."""
    structure = load_structure(reference)
    data = tomllib.loads(structure.text)
    if reference not in BUILTIN_STRUCTURES:  # a material CSV named relative to the structure file: absolute in the copy
        for spec in _material_specs(data):
            spec["file"] = os.path.abspath(Path(reference).parent / spec["file"])
    structure_data_with(data, changes)
    data["name"] = f"{data.get('name', 'structure')}_fitted"
    atomic_write_text(path, "# the structure with the scene fit's values (workbench fit)\n" + tomli_w.dumps(data))
    return str(path.resolve())


def fitted_scene_data(spec, table: FitTable, values: np.ndarray, out_dir: Path, base: dict | None = None,
                      scene_dir: Path | None = None) -> dict:
    """The scene file's data (``base``: parsed TOML, default ``spec.text``) with the fitted values in place;
    structure copies written to ``out_dir`` and named relative to ``scene_dir`` (where the scene file
    will lie; default ``out_dir``), so that a folder moved as a whole (a verify stage) keeps them."""
    data = base if base is not None else tomllib.loads(spec.text)
    scene_dir = scene_dir if scene_dir is not None else out_dir
    applied = apply_values(spec, table, values)
    for i, (entry, cd) in enumerate(zip(data.get("cd", []), applied.spec.cds, strict=True)):
        entry["center"] = [float(c) for c in cd.center]
        entry["normal"] = [float(c) for c in cd.normal]
        entry["structure"] = absolute_reference(cd.structure)
        if i in applied.structure_changes:
            copy = _structure_copy(cd.structure, applied.structure_changes[i], out_dir / f"cd{i}_structure.toml")
            entry["structure"] = os.path.relpath(copy, scene_dir.resolve())
        if "path" in cd.table:
            entry["table"] = {"path": absolute_reference(cd.table["path"])}
    for entry, grating in zip(data.get("grating", []), spec.gratings, strict=True):
        entry["structure"] = absolute_reference(grating.structure)
    light = data.setdefault("light", {})
    if any(p.kind == "light.center" for p in table.free):
        light["center"] = [float(c) for c in applied.spec.light.center]
    if any(p.kind == "light.size" for p in table.free):
        light["size"] = [float(c) for c in applied.spec.light.size]
    return data


def write_fitted_scene(spec, table: FitTable, values: np.ndarray, out_dir: Path, note: str, *, base: dict | None = None,
                       name: str = "fitted_scene.toml", structures: Path | None = None) -> Path:
    """DIR/fitted_scene.toml (module docstring); ``base``: another scene file's data to change (a photo's
    calibrated scene), ``name`` the file's name in ``out_dir``, ``structures`` the folder for the
    structure copies (default ``out_dir``)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    data = fitted_scene_data(spec, table, values, structures if structures is not None else out_dir, base, out_dir)
    header = "".join(f"# {line}\n" for line in note.splitlines())
    path = out_dir / name
    atomic_write_text(path, header + tomli_w.dumps(data))
    return path

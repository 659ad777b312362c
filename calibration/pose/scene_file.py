"""The input scene with a fitted camera, as a scene file ``workbench render`` loads.

The scene's own TOML is kept (every table and comment-free value as it was parsed) and its
``[camera]`` replaced by the fit in the explicit form renderer/scene.py reads:
``world_to_camera`` (4 x 4, OpenCV axes, metres), ``focal_px`` [fx, fy],
``principal_offset_px`` (from the image centre) and ``dist``; ``exposure`` becomes the
fitted photometric scale, so that a render of the file is the photo's linear values.
Paths the scene names relative to its own folder (structures, tables) are made absolute,
since the fitted file is written elsewhere.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import tomli_w

from rcwa.structure import BUILTIN_STRUCTURES
from renderer.camera import CameraModel
from renderer.scene import SceneSpec


def camera_table(camera: CameraModel, exposure: float, sensitivities: str, response: dict | str | None) -> dict:
    table = {
        "resolution": [camera.width, camera.height],
        "world_to_camera": [[float(v) for v in row] for row in camera.world_to_camera],
        "focal_px": [float(camera.fx), float(camera.fy)],
        "principal_offset_px": [float(camera.cx - (camera.width - 1) / 2), float(camera.cy - (camera.height - 1) / 2)],
        "dist": [float(d) for d in camera.dist],
        **({"model": camera.model} if camera.model != "pinhole" else {}),
        **({"xi": float(camera.xi)} if camera.model == "omnidir" else {}),
        "exposure": float(exposure),
        "sensitivities": sensitivities,
    }
    if response is not None:
        table["response"] = response
    return table


def fitted_scene_text(spec: SceneSpec, camera: CameraModel, exposure: float, note: str = "") -> str:
    """``spec``'s scene file with ``camera`` and ``exposure`` (see the module docstring)."""
    data = tomllib.loads(spec.text)
    old = data.get("camera", {})
    data["camera"] = camera_table(camera, exposure, spec.camera.sensitivities, old.get("response"))
    groups: list[tuple[str, Sequence[Any]]] = [("cd", spec.cds), ("grating", spec.gratings)]
    for key, elements in groups:
        for entry, element in zip(data.get(key, []), elements, strict=True):
            entry["structure"] = absolute_reference(element.structure)
            if "path" in element.table:
                entry["table"] = {"path": absolute_reference(element.table["path"])}
    header = "".join(f"# {line}\n" for line in note.splitlines()) if note else ""
    return header + tomli_w.dumps(data)


def absolute_reference(reference: str) -> str:
    """A path the scene resolved (relative to the scene's folder) made absolute; built-in names stay."""
    if reference in BUILTIN_STRUCTURES or not Path(reference).exists():
        return reference
    return os.path.abspath(reference)

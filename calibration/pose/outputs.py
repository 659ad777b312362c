"""What ``workbench calibrate pose`` writes: pose.json's content (result_json, versions,
the photometry note) and the outputs in OUT (pose.json, fitted_scene.toml), each written
atomically.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from calibration.pose.scene_file import fitted_scene_text
from calibration.pose.stages import PoseResult
from renderer.camera import CameraModel
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text
from workbench.core.version import versions as installed_versions

POSE_FORMAT = "workbench-calibrate-pose"
PHOTOMETRY_NOTE = ("exposure_scale: photo / render of the scene file (linear, 1 = the white level) over the walls; one "
                   "photo's brightness is exposure x light power, so light_power_scale is held at 1 and exposure_scale "
                   "is their product")


def versions() -> dict[str, str]:
    """Versions of what a pose fit depends on (recorded in every output)."""
    return installed_versions("numpy", "scipy", "opencv", "nlopt", "mitsuba")


def result_json(result: PoseResult) -> dict:
    """One photo's part of pose.json (and of calibration.json's ``photos``)."""
    return {"photo": result.photo, "camera": result.camera_json(), "fitted": list(result.unknowns.names),
            "std": result.std, "exposure_scale": result.exposure_scale, "exposure_scale_std": result.exposure_scale_std,
            "exposure_time_s": result.exposure_time_s, "residuals": result.residuals, "stages": result.log,
            "timings": result.timings}


def write_outputs(out: Path, name: str, record: dict, spec, camera: CameraModel, scale: float | None) -> None:
    """``name`` (JSON) and fitted_scene.toml in ``out``, each written atomically."""
    if out.exists() and not out.is_dir():
        raise UserInputError("is a file, not a folder", field="--out", expected="a folder for the results", got=str(out))
    out.mkdir(parents=True, exist_ok=True)
    exposure = spec.camera.exposure * (scale if scale is not None else 1.0)
    note = f"{spec.name} with the camera fitted by workbench calibrate ({name}); exposure: the photometric fit"
    atomic_write_text(out / "fitted_scene.toml", fitted_scene_text(spec, camera, exposure, note))
    atomic_write_text(out / name, json.dumps(record, indent=2, default=json_default) + "\n")


def json_default(value: object) -> object:
    """json.dumps' ``default`` for numpy scalars and arrays (as Python numbers and lists)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")

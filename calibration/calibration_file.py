"""calibration.json, the fitted cameras of a dataset's photos: its one writer and its one reader.

``calibrate DATASET`` (calibration.dataset) writes it through ``calibration_record`` and
``write_calibration``; the report, the scene fit, verify and the region tests read it through
``read_camera``, ``read_response``, ``exposure_relative_std`` and ``vignetting_record``.

The form read (that of the synthetic dataset's truth.json, which the calibration's output
shares): ``camera`` = {width, height, fx, fy, cx, cy, dist [k1, k2, p1, p2, k3],
world_to_camera: {file name: 4 x 4}} (OpenCV's model and axes, metres), optionally ``model``
(a lens model of renderer.lens, default ``pinhole``: ``dist`` then holds that model's
coefficients, and ``xi`` is the omnidir model's), optionally a
``scene`` (the scene's name or file it was made for) and ``camera_std`` (standard
deviations of fx, fy, cx, cy, dist, and ``rotation_deg``/``translation_m``) when the
calibration estimated them; calibration.json's own ``std`` (``calibration_record``) is read
too, with each pose's joint ``covariance`` of rotation, centre and intrinsics. The pose is
the one listed for the photo's file name, or the only one listed.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from calibration.board.board_file import BoardSpec
from calibration.pose.edge_fit import PoseSettings
from calibration.pose.outputs import PHOTOMETRY_NOTE, json_default, result_json, versions
from calibration.pose.scene_file import fitted_scene_text
from calibration.pose.stages import PoseResult
from calibration.raw.decode import load_response
from renderer.camera import CameraModel
from renderer.lens import LENS_MODELS
from renderer.scene import SceneSpec
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text

CALIBRATION_FORMAT = "workbench-calibration"
INTRINSIC_KEYS = ("width", "height", "fx", "fy", "cx", "cy")


@dataclass
class FittedCamera:
    """The camera for one photo, where it came from, and its uncertainties (when given)."""

    model: CameraModel
    source: str
    pose_key: str
    scene: str | None
    std: dict[str, Any] = field(default_factory=dict)
    lens_uncertainty: dict[str, Any] = field(default_factory=dict)  # calibration.json's intrinsics digest, if any

    def summary(self) -> dict[str, Any]:
        m = self.model
        fov_x = 2 * math.degrees(math.atan(0.5 * m.width / m.fx))
        origin = -m.world_to_camera[:3, :3].T @ m.world_to_camera[:3, 3]
        return {"source": self.source, "pose_of": self.pose_key, "scene": self.scene, "width": m.width,
                "height": m.height, "fx": m.fx, "fy": m.fy, "cx": m.cx, "cy": m.cy, "dist": list(m.dist),
                "model": m.model, **({"xi": m.xi} if m.model == "omnidir" else {}), "fov_x_deg": fov_x,
                "position_m": origin.tolist(), "std": self.std, **self.lens_uncertainty}


def _number(value: Any, where: str, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise UserInputError("must be a finite number", file=source, field=where, got=value)
    return float(value)


def _pose(value: Any, where: str, source: str) -> np.ndarray:
    matrix = np.asarray(value, dtype=object)
    if matrix.shape != (4, 4):
        raise UserInputError("must be a 4 x 4 matrix", file=source, field=where, got=value)
    matrix = np.array([[_number(x, where, source) for x in row] for row in matrix], float)
    rotation = matrix[:3, :3]
    if (np.max(np.abs(rotation)) > 1 + 1e-6  # a rotation's entries are cosines (and no overflow below)
            or not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6) or np.linalg.det(rotation) <= 0):
        raise UserInputError("its 3 x 3 part is not a rotation", file=source, field=where)
    return matrix


def read_camera(path: str | Path, photo_name: str) -> FittedCamera:
    """The camera of ``photo_name`` (a file name) from ``path`` (module docstring)."""
    path = Path(path)
    source = str(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise UserInputError("no such file", field="--calibration", got=source) from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise UserInputError(f"not a readable JSON file ({error})", field="--calibration", got=source) from None
    if not isinstance(data, dict) or not isinstance(data.get("camera"), dict):
        raise UserInputError("has no camera block", file=source, field="camera",
                             expected="{width, height, fx, fy, cx, cy, dist, world_to_camera: {file: 4x4}}")
    block = data["camera"]
    values = {}
    for key in INTRINSIC_KEYS:
        if key not in block:
            raise UserInputError("is missing", file=source, field=f"camera.{key}")
        values[key] = _number(block[key], f"camera.{key}", source)
    lens, dist, xi = _lens(block, source)
    poses = block.get("world_to_camera")
    if isinstance(poses, list):
        poses = {photo_name: poses}
    if not isinstance(poses, dict) or not poses:
        raise UserInputError("is missing", file=source, field="camera.world_to_camera",
                             expected="{file name: 4 x 4 matrix}")
    if photo_name in poses:
        key = photo_name
    elif len(poses) == 1:
        key = next(iter(poses))
    else:
        raise UserInputError(f"has no pose for the photo {photo_name!r}", file=source, field="camera.world_to_camera",
                             expected=f"one of {sorted(poses)[:8]}")
    model = CameraModel(int(values["width"]), int(values["height"]), values["fx"], values["fy"], values["cx"],
                        values["cy"], dist, _pose(poses[key], f"camera.world_to_camera.{key}", source), lens, xi)
    scene = data.get("scene")
    given = data.get("intrinsics")
    intrinsics: dict = given if isinstance(given, dict) else {}
    digest = {k: intrinsics[k] for k in ("projection_uncertainty_px", "cross_validation") if k in intrinsics}
    over_cd = (intrinsics.get("projection_uncertainty_cd_px") or {}).get(key)
    if isinstance(over_cd, dict):
        digest["projection_uncertainty_cd_px"] = over_cd  # this photo's CD (calibration.dataset)
    return FittedCamera(model, source, key, str(scene) if scene is not None else None, _camera_std(data, block, key, source),
                        digest)


def _lens(block: dict, source: str) -> tuple[str, tuple[float, ...], float]:
    """The camera block's lens model, its coefficients and xi (module docstring)."""
    name = block.get("model", "pinhole")
    if name not in LENS_MODELS:
        raise UserInputError("unknown lens model", file=source, field="camera.model",
                             expected=f"one of {', '.join(LENS_MODELS)}", got=name)
    names = LENS_MODELS[name].coefficients
    dist = block.get("dist", [0.0] * len(names))
    if not isinstance(dist, list) or len(dist) != len(names):
        raise UserInputError(f"must be {len(names)} numbers [{', '.join(names)}] for the {name} model", file=source,
                             field="camera.dist", got=dist)
    xi = _number(block.get("xi", 0.0), "camera.xi", source)
    if name != "omnidir" and xi != 0.0:
        raise UserInputError(f"is a parameter of the omnidir model, not of {name}", file=source, field="camera.xi")
    return name, tuple(_number(d, "camera.dist", source) for d in dist), xi


def _camera_std(data: dict, block: dict, key: str, source: str) -> dict[str, Any]:
    """The camera's standard deviations for the photo ``key``: ``camera_std`` (or the camera block's
    ``std``) as given, else calibration.json's top-level ``std`` (intrinsics, and per pose
    ``rotation_deg`` and ``camera_center_m`` per axis, whose RMS over the axes is the per-axis
    std reports.fringes.prediction_band takes, and the pose's joint ``covariance`` with the intrinsics
    where the calibration wrote it: calibration.pose.uncertainty.derived_std)."""
    given = data.get("camera_std") or block.get("std")
    if isinstance(given, dict):
        return given
    top = data.get("std")
    if not isinstance(top, dict):
        return {}
    out: dict[str, Any] = {k: float(top[k]) for k in ("fx", "fy", "cx", "cy") if _is_number(top.get(k))}
    pose = (top.get("poses") or {}).get(key) if isinstance(top.get("poses"), dict) else None
    for name, field_name in (("rotation_deg", "rotation_deg"), ("translation_m", "camera_center_m")):
        values = pose.get(field_name) if isinstance(pose, dict) else None
        if isinstance(values, list) and values and all(_is_number(v) for v in values):
            rms = math.hypot(*(float(v) for v in values)) / math.sqrt(len(values))  # hypot: 1e308 does not overflow
            if math.isfinite(rms):
                out[name] = rms
    joint = pose.get("covariance") if isinstance(pose, dict) else None
    if isinstance(joint, dict):
        out["covariance"] = _pose_covariance(joint, source)
    return out


def _pose_covariance(joint: dict, source: str) -> dict[str, Any]:
    """calibration.json's per-photo ``covariance`` (calibration.pose.uncertainty.POSE_READOUTS), checked."""
    names = joint.get("parameters")
    try:
        matrix = np.asarray(joint.get("matrix", []), float)
    except (TypeError, ValueError):  # ragged rows, or entries that are not numbers
        matrix = np.empty((0, 0))
    if (not isinstance(names, list) or matrix.shape != (len(names), len(names)) or not np.all(np.isfinite(matrix))
            or not np.allclose(matrix, matrix.T, rtol=1e-6, atol=1e-18)):
        raise UserInputError("is not a symmetric matrix named by its parameters", file=source,
                             field="std.poses.covariance", expected="{parameters: [names], matrix: [[...]] (square)}")
    return {"parameters": [str(n) for n in names], "matrix": matrix}


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def check_scene(camera: FittedCamera, spec, scene_argument: str) -> None:
    """A calibration made for another scene is refused (when it names its scene)."""
    if camera.scene is None:
        return
    names = {spec.name, scene_argument, Path(scene_argument).stem, Path(scene_argument).name}
    if camera.scene not in names and Path(camera.scene).stem not in names and _file_scene_name(camera.scene) not in names:
        raise UserInputError(f"the calibration was made for the scene {camera.scene!r}, not {spec.name!r}",
                             file=camera.source, field="scene", expected=f"a calibration of {spec.name!r}")


def _file_scene_name(scene: str) -> str | None:
    """The ``name`` inside a scene file the calibration names (a verify run's RUN/scene.toml), so that a
    scene derived from it (the scene fit's fitted_scene.toml keeps the name) is recognised."""
    path = Path(scene)
    if not path.is_file():
        return None
    try:
        name = tomllib.loads(path.read_text()).get("name")
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None
    return name if isinstance(name, str) else None


def read_response(path: str | Path) -> dict | None:
    """The fitted response in calibration.json (``response`` with ``points``), or None when it has none."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None  # read_camera has already refused an unreadable file
    response = data.get("response") if isinstance(data, dict) else None
    if not isinstance(response, dict) or "points" not in response:
        return None
    try:
        load_response({"points": response["points"]})
    except UserInputError as error:
        raise error.located(file=str(path), field_prefix="response") from None
    return {"points": response["points"]}


def exposure_relative_std(path: str | Path, photo_name: str) -> float | None:
    """The relative standard deviation of the photo's fitted exposure (calibration.json's
    ``std.exposure_scale`` over ``exposure_scale``, per photo), or None where none is stated."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None  # read_camera has already refused an unreadable file
    if not isinstance(data, dict):
        return None
    scale, std = data.get("exposure_scale"), (data.get("std") or {}).get("exposure_scale")
    if isinstance(scale, dict) and isinstance(std, dict):
        scale, std = scale.get(photo_name), std.get(photo_name)
    if not (_is_number(scale) and _is_number(std)):
        return None
    scale_value, std_value = float(scale), float(std)  # type: ignore[arg-type]
    return std_value / scale_value if scale_value > 0 else None


def vignetting_record(calibration: str | Path) -> dict | None:
    """The ``vignetting`` of a calibration.json (None for camera files without one)."""
    try:
        record = json.loads(Path(calibration).read_text()).get("vignetting")
    except (OSError, ValueError, AttributeError):
        return None  # read_camera reports what is wrong with the file
    return record if isinstance(record, dict) else None


# ---------------------------------------------------------------- the writer


def calibration_record(dataset: Path | str, scene: Path | str, spec: SceneSpec, files: dict[str, list[Path]],
                       intrinsics: dict | None,
                       lens_digest: dict, response: dict | None, results: dict[str, PoseResult], settings: PoseSettings,
                       board: BoardSpec | None, timings: dict) -> dict:
    """calibration.json's content for the poses ``results`` of a dataset's photos (module docstring).

    Parameters
    ----------
    dataset, scene, spec, files
        The dataset folder and scene as given, the scene loaded, the files by folder (dataset_files).
    intrinsics, lens_digest, response
        intrinsics.json's and response.json's records (None where not made), the lens's uncertainty digest.
    results, settings, board, timings
        Each photo's pose by file name, the pose fit's settings, the board, seconds per step.

    Returns
    -------
    dict
        The record that ``write_calibration`` writes.
    """
    first = next(iter(results.values()))
    c = first.camera
    scales = {name: r.exposure_scale for name, r in results.items()}
    per_second = {name: (r.exposure_scale / r.exposure_time_s if r.exposure_scale and r.exposure_time_s else None)
                  for name, r in results.items()}
    intrinsic_std = ({k: intrinsics["std"][k] for k in ("fx", "fy", "cx", "cy", "dist")} if intrinsics
                     else {k: first.std[k] for k in ("fx", "fy", "cx", "cy", "dist")})
    return {
        "format": CALIBRATION_FORMAT, "command": "workbench calibrate DATASET", "dataset": str(dataset), "scene": str(scene),
        "camera": {"width": c.width, "height": c.height, "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy,
                   "dist": [float(d) for d in c.dist], "model": c.model, **({"xi": c.xi} if c.model == "omnidir" else {}),
                   "fov_x_deg": first.camera_json()["fov_x_deg"],
                   "world_to_camera": {name: r.camera.world_to_camera.tolist() for name, r in results.items()}},
        "std": intrinsic_std | {"fov_x_deg": first.std["fov_x_deg"],
                                "poses": {name: {k: r.std[k] for k in ("rotation_deg", "rotation_total_deg",
                                                                       "camera_center_m", "covariance") if k in r.std}
                                          for name, r in results.items()},
                                "exposure_scale": {name: r.exposure_scale_std for name, r in results.items()}},
        "exposure_scale": scales, "exposure_time_s": {name: r.exposure_time_s for name, r in results.items()},
        "exposure_scale_per_second": per_second, "light_power_scale": 1.0, "photometry": PHOTOMETRY_NOTE,
        "response": _response_summary(response),
        "intrinsics": {"source": intrinsics["source"], "model": intrinsics.get("model", "pinhole"),
                       "model_choice": (intrinsics.get("model_choice") or {}).get("why"), "rms_px": intrinsics.get("rms_px"),
                       "distortion_terms": ((intrinsics.get("model_choice") or {}).get("terms") or {}).get("chosen"),
                       **lens_digest,
                       "views": intrinsics.get("views"), "flags": intrinsics.get("flags")} if intrinsics
        else {"source": f"fitted on {next(iter(results))} (no board views in calibration/)"},
        "residuals": {name: {k: v for k, v in r.residuals.items()} for name, r in results.items()},
        "cd_fringes": {name: r.log.get("cd_fringes") for name, r in results.items()},
        "photos": {name: result_json(r) for name, r in results.items()},
        "files": {k: [str(p) for p in v] for k, v in files.items()},
        "settings": {"board": None if board is None else board.to_json(), "pose": settings.to_json(), "scene": spec.source},
        "versions": versions(), "timings": timings,
    }


def _response_summary(response: dict | None) -> dict | None:
    if response is None:
        return None
    keys = ("method", "points", "linear", "raw_linearity", "times_s", "files")
    return {k: response[k] for k in keys if k in response}


def write_calibration(out: Path, record: dict, spec: SceneSpec, results: dict[str, PoseResult], intrinsics: dict | None,
                      response: dict | None) -> None:
    """DIR/calibration.json with ``record``, and beside it the scene files of the fitted cameras
    (fitted_scene.toml and scenes/NAME.toml), intrinsics.json and response.json, each written atomically."""
    out.mkdir(parents=True, exist_ok=True)
    for i, (name, result) in enumerate(results.items()):
        exposure = spec.camera.exposure * (result.exposure_scale if result.exposure_scale is not None else 1.0)
        text = fitted_scene_text(spec, result.camera, exposure,
                                 f"{spec.name} with the camera fitted to {name} by workbench calibrate")
        atomic_write_text(out / "scenes" / f"{Path(name).stem}.toml", text)
        if i == 0:
            atomic_write_text(out / "fitted_scene.toml", text)
    if intrinsics is not None:
        atomic_write_text(out / "intrinsics.json", json.dumps(intrinsics, indent=2, default=json_default) + "\n")
    if response is not None:
        atomic_write_text(out / "response.json", json.dumps(response, indent=1, default=json_default) + "\n")
    atomic_write_text(out / "calibration.json", json.dumps(record, indent=2, default=json_default) + "\n")

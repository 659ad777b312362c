"""What ``workbench calibrate pose`` reads and starts from: intrinsics.json, a response
curve to linearise a non-raw photo, and the scene's camera and renderer at the photo's
resolution.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from calibration.pose.photo import Photo
from renderer.camera import CameraModel
from renderer.lens import LENS_MODELS
from renderer.render import with_resolution
from renderer.rerender import FitRenderer
from workbench.core.errors import UserInputError


def load_intrinsics(path: str | Path) -> dict:
    """intrinsics.json (``workbench calibrate intrinsics``): width, height, fx, fy, cx, cy,
    dist [k1, k2, p1, p2, k3] (or the coefficients of its ``model``, renderer.lens; ``xi`` for
    omnidir) and, when present, ``std``."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise UserInputError(f"cannot be read ({exc})", file=path, expected="intrinsics.json") from None
    except ValueError as exc:
        raise UserInputError(f"is not JSON ({exc})", file=path, expected="intrinsics.json") from None
    if not isinstance(data, dict):
        raise UserInputError("is not an intrinsics file", file=path, expected="a JSON object")
    for key in ("width", "height", "fx", "fy", "cx", "cy", "dist"):
        if key not in data:
            raise UserInputError("is missing", file=path, field=key, expected="what `workbench calibrate intrinsics` writes")
    model = data.get("model", "pinhole")
    if model not in LENS_MODELS:
        raise UserInputError("unknown lens model", file=path, field="model", expected=f"one of {', '.join(LENS_MODELS)}",
                             got=model)
    dist, names = data["dist"], LENS_MODELS[model].coefficients
    counts = (4, 5) if model == "pinhole" else (len(names),)
    if not isinstance(dist, list) or len(dist) not in counts or not all(isinstance(d, (int, float)) for d in dist):
        raise UserInputError(f"must be {' or '.join(map(str, counts))} numbers", file=path, field="dist",
                             expected=f"[{', '.join(names)}]", got=dist)
    xi = data.get("xi", 0.0) if model == "omnidir" else 0.0
    if not isinstance(xi, (int, float)):
        raise UserInputError("must be a number", file=path, field="xi", got=xi)
    for key in ("fx", "fy", "width", "height"):
        if not isinstance(data[key], (int, float)) or not data[key] > 0:
            raise UserInputError("must be a positive number", file=path, field=key, got=data[key])
    return {"width": int(data["width"]), "height": int(data["height"]), "fx": float(data["fx"]), "fy": float(data["fy"]),
            "cx": float(data["cx"]), "cy": float(data["cy"]), "dist": tuple(float(d) for d in (list(dist) + [0.0])[:len(names)]),
            "model": model, "xi": float(xi),
            "std": data.get("std") if isinstance(data.get("std"), dict) else None, "source": str(path)}


def load_inverse_response(path: str | Path):
    """response.json's (or truth.json's form) ``points``, pairs of normalised irradiance and
    value, as the inverse: value -> irradiance (piecewise linear, monotone)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
        points = np.asarray(data["points"] if "points" in data else data["response"]["points"], float)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise UserInputError(f"holds no response curve ({type(exc).__name__})", file=path,
                             expected="response.json with points [[irradiance, value], ...]") from None
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 2 or np.any(np.diff(points[:, 1]) <= 0):
        raise UserInputError("the response's points must be pairs with increasing values", file=path, field="points")
    return lambda values: np.interp(values, points[:, 1], points[:, 0]).astype(np.float32)


def start_camera(spec, photo: Photo, intrinsics: dict | None) -> CameraModel:
    """The scene's camera at the photo's resolution, with the given intrinsics when there are
    (else with square pixels)."""
    if intrinsics is not None and (intrinsics["width"], intrinsics["height"]) != (photo.width, photo.height):
        raise UserInputError("the photo's size differs from the intrinsics'", file=photo.path,
                             expected=f"{intrinsics['width']} x {intrinsics['height']} pixels as in {intrinsics['source']}",
                             got=f"{photo.width} x {photo.height}")
    camera = with_resolution(spec, (photo.width, photo.height)).camera.model
    if intrinsics is not None:
        return dataclasses.replace(camera, fx=intrinsics["fx"], fy=intrinsics["fy"], cx=intrinsics["cx"],
                                   cy=intrinsics["cy"], dist=intrinsics["dist"],
                                   model=intrinsics.get("model", "pinhole"), xi=intrinsics.get("xi", 0.0))
    # To be fitted: square pixels (fy = fx; the fit keeps the ratio), which a resolution's
    # rounding in the scene file (326 x 245 for 25 x 18.8 mm) would otherwise bend by 0.4 %.
    focal = math.sqrt(camera.fx * camera.fy)
    return dataclasses.replace(camera, fx=focal, fy=focal)


def fit_renderer(spec, camera: CameraModel, spp: int):
    """renderer.rerender.FitRenderer of ``spec`` seen by ``camera`` (its resolution and intrinsics)."""
    seen = dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, model=camera))
    return FitRenderer(seen, resolution=(camera.width, camera.height), spp=spp)

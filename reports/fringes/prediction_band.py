"""Cameras drawn within the calibration's standard deviations: the prediction's uncertainty band.

The report predicts the CD's band edges again for each drawn camera (reports.report.
prediction_band); the spread of those edges about the fitted camera's is the band plotted
on the fringe plot.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

from renderer.camera import CameraModel

CAMERA_STD_KEYS = ("fx", "fy", "cx", "cy", "rotation_deg", "translation_m")


def draw_cameras(camera: CameraModel, std: dict, count: int, seed: int = 0) -> list[CameraModel]:
    """``count`` cameras drawn about ``camera`` within the calibration's standard deviations
    (calibration.calibration_file: ``fx``, ``fy``, ``cx``, ``cy`` in pixels, ``rotation_deg`` a small
    rotation about each camera axis, ``translation_m`` along each axis; keys not given stay
    fixed). Each draw is ``camera + std * z`` with z standard normal from ``seed``, so the same
    seed with twice the std gives draws twice as far (the band's width scales with the std)."""
    rng = np.random.default_rng(seed)
    sigma = {k: float(std[k]) if isinstance(std.get(k), (int, float)) else 0.0 for k in CAMERA_STD_KEYS}
    out = []
    for _ in range(count):
        z = rng.standard_normal(10)  # the same numbers whichever keys are given
        out.append(moved_camera(camera, [sigma[k] * z[i] for i, k in enumerate(("fx", "fy", "cx", "cy"))],
                                sigma["rotation_deg"] * z[4:7], sigma["translation_m"] * z[7:10]))
    return out


def moved_camera(camera: CameraModel, intrinsics: list[float], rotation_deg: np.ndarray,
                 translation_m: np.ndarray) -> CameraModel:
    """``camera`` with fx, fy, cx, cy moved by ``intrinsics`` (px), turned by the small rotation
    vector ``rotation_deg`` about the camera's axes and shifted by ``translation_m`` along them."""
    changes = {k: getattr(camera, k) + d for k, d in zip(("fx", "fy", "cx", "cy"), intrinsics, strict=True)}
    pose = camera.world_to_camera.copy()
    turn = Rotation.from_rotvec(np.radians(np.asarray(rotation_deg, float))).as_matrix()
    pose[:3, :3], pose[:3, 3] = turn @ pose[:3, :3], turn @ pose[:3, 3]
    pose[:3, 3] += np.asarray(translation_m, float)
    return dataclasses.replace(camera, world_to_camera=pose, **changes)

"""The camera model shared by rendering and calibration: OpenCV's pinhole with distortion.

Conventions (OpenCV, "Camera Calibration and 3D Reconstruction"): camera axes x right,
y down, z forward; pixel (u, v) = (fx x' + cx, fy y' + cy) with (x', y') the distorted
normalized coordinates of the radial-tangential model (k1, k2, p1, p2, k3); world units
metres; ``world_to_camera`` is a 4 x 4 rigid transform. Pixel centres sit at integer
coordinates (OpenCV), so pixel (0, 0) covers [-0.5, 0.5]^2.

Rendering: Mitsuba renders an ideal pinhole image (square pixels, centred principal
point, no distortion) wide enough to cover the distorted field; every output pixel is
then undistorted (cv2.undistortPoints) into that image and resampled (cv2.remap). So the
principal point, fx != fy and the distortion all go through one warp, and a point
projected with ``CameraModel.project`` lands where the renderer draws it
(tests/renderer/test_camera.py: within 0.5 pixel).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

WARP_MARGIN_PX = 4
UNDISTORT_ITERATIONS = 100


def look_at(origin, target, up) -> np.ndarray:
    """World-to-camera transform (OpenCV axes) of a camera at ``origin`` looking at ``target``."""
    origin, target, up = (np.asarray(v, dtype=float) for v in (origin, target, up))
    z = target - origin
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-12:
        raise ValueError("look_at: the up vector is parallel to the viewing direction")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ origin
    return T


@dataclass(frozen=True)
class CameraModel:
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    dist: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    world_to_camera: np.ndarray = field(default_factory=lambda: np.eye(4))

    @classmethod
    def from_fov(cls, width: int, height: int, fov_x_deg: float, world_to_camera: np.ndarray,
                 dist=(0.0, 0.0, 0.0, 0.0, 0.0), principal_offset_px=(0.0, 0.0)) -> "CameraModel":
        f = 0.5 * width / math.tan(math.radians(fov_x_deg) / 2)
        k1, k2, p1, p2, k3 = (float(d) for d in dist)
        return cls(width, height, f, f, (width - 1) / 2 + principal_offset_px[0], (height - 1) / 2 + principal_offset_px[1],
                   (k1, k2, p1, p2, k3), np.asarray(world_to_camera, dtype=float))

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def dist_array(self) -> np.ndarray:
        return np.asarray(self.dist, dtype=float)

    def project(self, points_world: np.ndarray) -> np.ndarray:
        """Pixel coordinates (N, 2) of world points (N, 3), distortion included (cv2.projectPoints)."""
        R = self.world_to_camera[:3, :3]
        t = self.world_to_camera[:3, 3]
        rvec, _ = cv2.Rodrigues(R)
        pixels, _ = cv2.projectPoints(np.asarray(points_world, dtype=float).reshape(-1, 1, 3), rvec, t, self.K, self.dist_array)
        return pixels.reshape(-1, 2)

    def normalized(self, pixels: np.ndarray) -> np.ndarray:
        """Undistorted normalized image coordinates (N, 2) of pixels (N, 2): the inverse of
        project's lens model. OpenCV's cv2.undistortPoints stops, by default, after 5 fixed-point
        iterations, which leaves up to ~0.2 px of error where the distortion is strong
        (image corners); iterating to convergence makes the inverse exact to 1e-9 px."""
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, UNDISTORT_ITERATIONS, 1e-12)
        return cv2.undistortPoints(np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2), self.K, self.dist_array,
                                   criteria=criteria).reshape(-1, 2)

    def pixel_rays(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The camera centre (3,) and unit world directions (N, 3) through pixel positions
        (N, 2): the lens model inverted (``normalized``), then the pose."""
        xy = self.normalized(np.asarray(pixels, float))
        local = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)
        rotation = self.world_to_camera[:3, :3]
        origin = -rotation.T @ self.world_to_camera[:3, 3]
        directions = local @ rotation  # rows: R^T d
        return origin, directions / np.linalg.norm(directions, axis=1, keepdims=True)

    # ---------------------------------------------------------------- rendering

    def pinhole_plan(self) -> "PinholePlan":
        """The ideal pinhole image Mitsuba renders, covering every output pixel."""
        u, v = np.meshgrid(np.arange(self.width, dtype=float), np.arange(self.height, dtype=float))
        border = np.concatenate([np.stack([u[0], v[0]], 1), np.stack([u[-1], v[-1]], 1),
                                 np.stack([u[:, 0], v[:, 0]], 1), np.stack([u[:, -1], v[:, -1]], 1)])
        normalized = self.normalized(border)
        f = max(self.fx, self.fy)
        half_w = math.ceil(np.max(np.abs(normalized[:, 0])) * f) + WARP_MARGIN_PX
        half_h = math.ceil(np.max(np.abs(normalized[:, 1])) * f) + WARP_MARGIN_PX
        width, height = 2 * half_w, 2 * half_h
        fov_x = 2 * math.degrees(math.atan(0.5 * width / f))
        return PinholePlan(width, height, f, fov_x, self.mitsuba_to_world())

    def mitsuba_to_world(self) -> np.ndarray:
        """Mitsuba's sensor to_world: its local axes are x left, y up, z forward."""
        camera_to_world = np.linalg.inv(self.world_to_camera)
        return camera_to_world @ np.diag([-1.0, -1.0, 1.0, 1.0])

    def warp(self, pinhole_image: np.ndarray, plan: "PinholePlan") -> np.ndarray:
        """Resample the ideal pinhole image into this camera's image (distortion, principal point)."""
        u, v = np.meshgrid(np.arange(self.width, dtype=np.float64), np.arange(self.height, dtype=np.float64))
        pts = np.stack([u.ravel(), v.ravel()], 1).reshape(-1, 1, 2)
        normalized = self.normalized(pts)
        map_x = (normalized[:, 0] * plan.focal + (plan.width - 1) / 2).reshape(self.height, self.width).astype(np.float32)
        map_y = (normalized[:, 1] * plan.focal + (plan.height - 1) / 2).reshape(self.height, self.width).astype(np.float32)
        return cv2.remap(np.ascontiguousarray(pinhole_image, dtype=np.float32), map_x, map_y, cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=0)


@dataclass(frozen=True)
class PinholePlan:
    width: int
    height: int
    focal: float
    fov_x_deg: float
    to_world: np.ndarray

    def sensor_dict(self, mi, spp: int, film_extra: dict | None = None) -> dict:
        return {
            "type": "perspective", "fov": self.fov_x_deg, "fov_axis": "x",
            "to_world": mi.ScalarTransform4f(self.to_world.tolist()),
            "film": {"type": "hdrfilm", "width": self.width, "height": self.height, "rfilter": {"type": "box"},
                     **(film_extra or {})},
            "sampler": {"type": "independent", "sample_count": spp},
        }

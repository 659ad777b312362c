"""The camera model shared by rendering and calibration: a lens model of renderer.lens
(OpenCV's pinhole with distortion by default; rational, fisheye, omnidir).

Conventions (OpenCV, "Camera Calibration and 3D Reconstruction"): camera axes x right,
y down, z forward; pixel (u, v) = (fx x' + cx, fy y' + cy) with (x', y') the distorted
normalized coordinates of the lens model (the pinhole's radial-tangential k1, k2, p1, p2,
k3; renderer.lens for the others); world units metres; ``world_to_camera`` is a 4 x 4
rigid transform. Pixel centres sit at integer coordinates (OpenCV), so pixel (0, 0) covers
[-0.5, 0.5]^2.

Rendering: Mitsuba renders an ideal pinhole image (square pixels, centred principal
point, no distortion) wide enough to cover the distorted field; every output pixel is
then undistorted (cv2.undistortPoints) into that image and resampled (cv2.remap). So the
principal point, fx != fy and the distortion all go through one warp, and a point
projected with ``CameraModel.project`` lands where the renderer draws it
(tests/renderer/test_camera.py: within 0.5 pixel; tests/renderer/test_camera_lenses.py: the
warp's maps reproduce every model's projection to 1e-6 px).

Wide lenses: an ideal pinhole holds rays up to MAX_HALF_FIELD_DEG off the axis (150 degrees
across); a camera whose image reaches further is refused (UserInputError). The pinhole image
is sampled at least as densely as the output everywhere: its focal length is the output's
largest local sampling density of normalized coordinates (a barrel-distorting lens's is at
its centre, about fx, or fx / (1 + xi) for omnidir; a pincushion's at its edges), up to
MAX_PLAN_SIDE pixels a side.
The pinhole model keeps max(fx, fy), as its renders always had.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from renderer import lens
from workbench.core.errors import UserInputError

WARP_MARGIN_PX = 4
MAX_HALF_FIELD_DEG = 75.0   # rays an ideal pinhole image can hold at a sane size (tan 75 deg = 3.7 focal lengths)
MAX_PLAN_SIDE = 16384       # pixels a side of the pinhole image Mitsuba renders
DENSITY_STEP_PX = 4         # output-pixel spacing at which the pinhole image's needed density is measured


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
    dist: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)   # the lens model's coefficients (renderer.lens)
    world_to_camera: np.ndarray = field(default_factory=lambda: np.eye(4))
    model: str = "pinhole"                                  # renderer.lens.LENS_MODELS
    xi: float = 0.0                                         # Mei's xi (omnidir only)

    def __post_init__(self) -> None:
        lens.check_coefficients(self.model, self.dist, self.xi)

    @classmethod
    def from_fov(cls, width: int, height: int, fov_x_deg: float, world_to_camera: np.ndarray,
                 dist=(0.0, 0.0, 0.0, 0.0, 0.0), principal_offset_px=(0.0, 0.0), model: str = "pinhole",
                 xi: float = 0.0) -> "CameraModel":
        """The focal length from the horizontal field of view of an ideal pinhole of the same width."""
        f = 0.5 * width / math.tan(math.radians(fov_x_deg) / 2)
        coefficients = lens.check_coefficients(model, dist, float(xi))
        return cls(width, height, f, f, (width - 1) / 2 + principal_offset_px[0], (height - 1) / 2 + principal_offset_px[1],
                   coefficients, np.asarray(world_to_camera, dtype=float), model, float(xi))

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def dist_array(self) -> np.ndarray:
        return np.asarray(self.dist, dtype=float)

    def project(self, points_world: np.ndarray) -> np.ndarray:
        """Pixel coordinates (N, 2) of world points (N, 3), distortion included (renderer.lens.project:
        cv2.projectPoints for the pinhole)."""
        rvec, _ = cv2.Rodrigues(self.world_to_camera[:3, :3])
        return lens.project(self.model, points_world, rvec, self.world_to_camera[:3, 3], self.K, self.dist_array, self.xi)

    def project_with_jacobian(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (N, 2) and their Jacobian in cv2.projectPoints' columns (renderer.lens.project_with_jacobian)."""
        rvec, _ = cv2.Rodrigues(self.world_to_camera[:3, :3])
        return lens.project_with_jacobian(self.model, points_world, rvec, self.world_to_camera[:3, 3], self.K,
                                          self.dist_array, self.xi)

    def normalized(self, pixels: np.ndarray) -> np.ndarray:
        """Undistorted normalized image coordinates (N, 2) of pixels (N, 2): the inverse of
        project's lens model. OpenCV's cv2.undistortPoints stops, by default, after 5 fixed-point
        iterations, which leaves up to ~0.2 px of error where the distortion is strong
        (image corners); iterating to convergence makes the inverse exact to 1e-9 px (the
        other models: renderer.lens.normalized, NaN beyond the lens's reach)."""
        return lens.normalized(self.model, pixels, self.K, self.dist_array, self.xi)

    def half_field_deg(self) -> float:
        """The largest angle (degrees) between the optical axis and the ray of a pixel on the image's border."""
        rays = self.normalized(self._border())
        if not np.all(np.isfinite(rays)):
            return 90.0
        return float(np.degrees(np.arctan(np.max(np.linalg.norm(rays, axis=1)))))

    def _border(self) -> np.ndarray:
        u, v = np.meshgrid(np.arange(self.width, dtype=float), np.arange(self.height, dtype=float))
        return np.concatenate([np.stack([u[0], v[0]], 1), np.stack([u[-1], v[-1]], 1),
                               np.stack([u[:, 0], v[:, 0]], 1), np.stack([u[:, -1], v[:, -1]], 1)])

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
        """The ideal pinhole image Mitsuba renders, covering every output pixel (module docstring)."""
        normalized = self.normalized(self._border())
        f = max(self.fx, self.fy)
        if self.model != "pinhole":
            self._check_field(normalized)
            f = self._needed_focal()
        half_w = math.ceil(np.max(np.abs(normalized[:, 0])) * f) + WARP_MARGIN_PX
        half_h = math.ceil(np.max(np.abs(normalized[:, 1])) * f) + WARP_MARGIN_PX
        width, height = 2 * half_w, 2 * half_h
        if max(width, height) > MAX_PLAN_SIDE:
            raise UserInputError(f"the lens needs a {width} x {height} pixel pinhole image to render, over "
                                 f"{MAX_PLAN_SIDE} a side", field="camera", expected="a narrower field or a smaller image")
        fov_x = 2 * math.degrees(math.atan(0.5 * width / f))
        return PinholePlan(width, height, f, fov_x, self.mitsuba_to_world())

    def _check_field(self, border_rays: np.ndarray) -> None:
        reach = np.linalg.norm(border_rays, axis=1)
        if not np.all(np.isfinite(reach)) or np.degrees(np.arctan(np.max(reach))) > MAX_HALF_FIELD_DEG:
            seen = 90.0 if not np.all(np.isfinite(reach)) else float(np.degrees(np.arctan(np.max(reach))))
            raise UserInputError(f"the {self.model} lens sees {seen:.1f} degrees off its axis at the image's border; "
                                 f"the renderer's pinhole image holds at most {MAX_HALF_FIELD_DEG:g} "
                                 f"({2 * MAX_HALF_FIELD_DEG:g} degrees across)", field="camera",
                                 expected="a narrower field of view (crop the image, or a longer focal length)")

    def _needed_focal(self) -> float:
        """The pinhole focal length (px) at which its pixels are no coarser than the output's
        anywhere: one over the smallest normalized-coordinate step between output pixels."""
        step = DENSITY_STEP_PX
        u, v = np.meshgrid(np.arange(0, self.width, step, dtype=float), np.arange(0, self.height, step, dtype=float))
        grid = self.normalized(np.stack([u.ravel(), v.ravel()], 1)).reshape(u.shape + (2,))
        steps = [np.linalg.norm(np.diff(grid, axis=axis), axis=-1) / step for axis in (0, 1)]
        smallest = min(float(np.nanmin(s)) for s in steps if s.size)
        return 1.0 / smallest if smallest > 0 else max(self.fx, self.fy)

    def mitsuba_to_world(self) -> np.ndarray:
        """Mitsuba's sensor to_world: its local axes are x left, y up, z forward."""
        camera_to_world = np.linalg.inv(self.world_to_camera)
        return camera_to_world @ np.diag([-1.0, -1.0, 1.0, 1.0])

    def warp(self, pinhole_image: np.ndarray, plan: "PinholePlan") -> np.ndarray:
        """Resample the ideal pinhole image into this camera's image (distortion, principal point)."""
        u, v = np.meshgrid(np.arange(self.width, dtype=np.float64), np.arange(self.height, dtype=np.float64))
        pts = np.stack([u.ravel(), v.ravel()], 1).reshape(-1, 1, 2)
        normalized = np.nan_to_num(self.normalized(pts), nan=-1e6)  # beyond the lens: outside the image, black
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

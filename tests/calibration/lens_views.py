"""Board corners seen through any lens model (renderer.lens), for the lens-model tests.

``corner_views``: a 9 x 6 board (3 cm squares) held at 20-40 cm, aimed at a random pixel
anywhere in the image (corners included, where a wide lens distorts most), its face turned
15-40 degrees from the camera about a random axis and rolled a little; kept only when every
corner lands inside the image. The corners are the model's exact projections plus Gaussian
noise of ``noise_px`` (a good detector on a sharp view: 0.05 px).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from calibration.intrinsics import board_points
from renderer import lens

BOARD = board_points((9, 6), 0.03)


def board_pose(model: str, K: np.ndarray, dist: np.ndarray, xi: float, pixel: np.ndarray, distance: float,
               tilt_deg: float, axis: np.ndarray, roll: float) -> tuple[np.ndarray, np.ndarray]:
    """(rvec, tvec) of a board whose centre is on ``pixel``'s ray at ``distance``, turned from face-on."""
    ray = lens.normalized(model, pixel[None], K, dist, xi)[0]
    d = np.array([ray[0], ray[1], 1.0])
    d /= np.linalg.norm(d)
    z = -d
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.column_stack([x, np.cross(z, x), z])
    R = R @ Rotation.from_rotvec(np.radians(tilt_deg) * axis).as_matrix() @ Rotation.from_rotvec([0, 0, roll]).as_matrix()
    return cv2.Rodrigues(R)[0].ravel(), d * distance


def corner_views(model: str, K: np.ndarray, dist, xi: float, size: tuple[int, int], count: int, seed: int,
                 noise_px: float = 0.05) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Board points (N, 3) and noisy corners (N, 1, 2) of ``count`` views (module docstring)."""
    rng = np.random.default_rng(seed)
    dist = np.asarray(dist, float)
    points, corners = [], []
    while len(points) < count:
        pixel = rng.uniform([20.0, 20.0], [size[0] - 20.0, size[1] - 20.0])
        axis = np.r_[rng.normal(size=2), 0.0]
        rvec, tvec = board_pose(model, K, dist, xi, pixel, rng.uniform(0.2, 0.4), rng.uniform(15, 40),
                                axis / np.linalg.norm(axis), rng.uniform(-0.3, 0.3))
        camera_points = BOARD @ cv2.Rodrigues(rvec)[0].T + tvec
        if np.any(camera_points[:, 2] < 0.05):
            continue
        pix = lens.project(model, BOARD, rvec, tvec, K, dist, xi)
        if np.any(pix < 2) or np.any(pix > np.array(size) - 3):
            continue
        points.append(BOARD.astype(np.float32))
        corners.append((pix + rng.normal(0.0, noise_px, pix.shape)).astype(np.float32).reshape(-1, 1, 2))
    return points, corners

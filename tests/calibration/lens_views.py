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

from calibration.intrinsics.calibrate import board_points
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


def board_images(model: str, K: np.ndarray, dist, xi: float, size: tuple[int, int], count: int, seed: int,
                 supersample: int = 3, square_m: float = 0.03) -> list[np.ndarray]:
    """``count`` grey images (float, H x W) of the 9 x 6 board (a light margin of one square, mid-grey
    beyond) seen exactly through the lens: each pixel the mean of ``supersample``^2 samples, each
    sample's ray (renderer.lens.normalized, once for all views) met with the board's plane.
    Poses as ``corner_views`` draws them, kept when the whole board with its margin is in the image."""
    rng = np.random.default_rng(seed)
    dist = np.asarray(dist, float)
    n = supersample
    ys, xs = np.mgrid[0:size[1] * n, 0:size[0] * n]
    samples = np.stack([(xs.ravel() + 0.5) / n - 0.5, (ys.ravel() + 0.5) / n - 0.5], 1)
    rays = np.c_[lens.normalized(model, samples, K, dist, xi), np.ones(len(samples))]
    cols, rows = 10, 7                                           # squares of the 9 x 6 inner-corner board
    outline = np.array([[sx * (cols / 2 + 1), sy * (rows / 2 + 1), 0.0] for sx in (-1, 1) for sy in (-1, 1)]) * square_m
    images = []
    while len(images) < count:
        pixel = rng.uniform([20.0, 20.0], [size[0] - 20.0, size[1] - 20.0])
        axis = np.r_[rng.normal(size=2), 0.0]
        rvec, tvec = board_pose(model, K, dist, xi, pixel, rng.uniform(0.25, 0.45), rng.uniform(15, 40),
                                axis / np.linalg.norm(axis), rng.uniform(-0.3, 0.3))
        R = cv2.Rodrigues(rvec)[0]
        edge = np.concatenate([outline[i] + np.linspace(0, 1, 12)[:, None] * (outline[j] - outline[i])
                               for i, j in ((0, 1), (1, 3), (3, 2), (2, 0))])
        pix = lens.project(model, edge, rvec, tvec, K, dist, xi)
        if np.any((edge @ R.T + tvec)[:, 2] < 0.05) or np.any(pix < 1) or np.any(pix > np.array(size) - 2):
            continue
        plane = np.linalg.inv(np.column_stack([R[:, 0], R[:, 1], tvec]))   # normalized ray -> board (x, y, w)
        board = rays @ plane.T
        bx, by = board[:, 0] / board[:, 2] / square_m, board[:, 1] / board[:, 2] / square_m
        in_squares = (np.abs(bx) < cols / 2) & (np.abs(by) < rows / 2)
        on_board = (np.abs(bx) < cols / 2 + 1) & (np.abs(by) < rows / 2 + 1) & (board[:, 2] > 0)
        dark = ((np.floor(bx + cols / 2) + np.floor(by + rows / 2)) % 2 == 0) & in_squares
        value = np.where(on_board, np.where(dark, 0.05, 0.8), 0.3)
        images.append(value.reshape(size[1], n, size[0], n).mean(axis=(1, 3)))
    return images

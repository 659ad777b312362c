"""Checkerboard corners in a photograph: found by OpenCV, refined by point symmetry.

OpenCV's detector (``findChessboardCornersSB``) finds the board and orders the corners;
its own sub-pixel estimates, and ``cornerSubPix``'s, are biased by perspective and
weigh noisy gradients (measured on the synthetic calibration set, 640 x 480: 0.21 and
0.25 px RMS against the truth). Each corner is therefore moved to the centre of point
symmetry of the image around it (0.09 px on the same views; 0.02-0.05 px on analytically
rasterized boards). The symmetry criterion is that of saddle-point / symmetry corner
detectors (e.g. D. Chen & G. Zhang, "A new sub-pixel detector for X-corners in camera
calibration targets", WSCG 2005; L. Lucchese & S. K. Mitra, "Using saddle points for
subpixel feature detection in camera calibration targets", APCCAS 2002), written here as
a least-squares fit with a shading term.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.optimize import least_squares


def find_board_corners(grey: np.ndarray, pattern: tuple[int, int]) -> tuple[bool, np.ndarray | None]:
    """(found, corners (N, 1, 2) float32 in pixels) of a ``pattern`` = (cols, rows) inner-corner
    checkerboard in ``grey`` (linear, about 0-1): OpenCV's detector, then point-symmetry
    refinement."""
    grey8 = np.rint(255 * np.clip(grey, 0, 1)).astype(np.uint8)
    found, corners = cv2.findChessboardCornersSB(grey8, pattern, flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
    if not found:
        return False, None
    return True, refine_by_symmetry(grey, corners, pattern)


def _neighbour_spacing(grid: np.ndarray) -> np.ndarray:
    """Distance from each corner of a (rows, cols, 2) grid to its nearest grid neighbour."""
    rows, cols = grid.shape[:2]
    spacing = np.full((rows, cols), np.inf)
    along = np.linalg.norm(np.diff(grid, axis=1), axis=2)
    across = np.linalg.norm(np.diff(grid, axis=0), axis=2)
    spacing[:, :-1] = np.minimum(spacing[:, :-1], along)
    spacing[:, 1:] = np.minimum(spacing[:, 1:], along)
    spacing[:-1] = np.minimum(spacing[:-1], across)
    spacing[1:] = np.minimum(spacing[1:], across)
    return spacing


def refine_by_symmetry(grey: np.ndarray, corners: np.ndarray, pattern: tuple[int, int]) -> np.ndarray:
    """Each corner moved to the centre of point symmetry of the image around it.

    A checkerboard corner is point-symmetric (q + v and q - v fall on the same colour)
    however the board is tilted, and so is its image after pixel averaging and blur:
    locally the pattern is an affine image of the board, which keeps the symmetry. So the
    q that best matches I(q + v) with I(q - v) over a disc of radius 0.7 times the
    distance to the nearest neighbouring corner is unbiased by perspective. A linear
    shading term g, I(q + v) - I(q - v) = (g . v)(I(q + v) + I(q - v)), takes up a
    light's fall-off across the board.
    """
    image = np.ascontiguousarray(grey, dtype=np.float32)
    cols, rows = pattern
    grid = corners.reshape(rows, cols, 2).astype(float)
    refined = [_refine_one(image, q0, d) for q0, d in zip(grid.reshape(-1, 2), _neighbour_spacing(grid).ravel())]
    return np.array(refined, dtype=np.float32).reshape(-1, 1, 2)


def _refine_one(image: np.ndarray, q0: np.ndarray, spacing: float) -> np.ndarray:
    radius = max(2.0, 0.7 * spacing)
    n = int(np.ceil(radius))
    vy, vx = np.mgrid[-n:n + 1, -n:n + 1].astype(float)
    half = (vx**2 + vy**2 <= radius**2) & ((vy > 0) | ((vy == 0) & (vx > 0)))  # each pair (v, -v) once
    v = np.stack([vx[half], vy[half]], 1)

    def residual(p):
        at = np.concatenate([p[:2] + v, p[:2] - v]).astype(np.float32)
        s = cv2.remap(image, at[None, :, 0].copy(), at[None, :, 1].copy(), cv2.INTER_CUBIC).ravel()
        plus, minus = s[:len(v)], s[len(v):]
        return plus - minus - (v @ p[2:]) * (plus + minus)

    fit = least_squares(residual, np.r_[q0, 0.0, 0.0], diff_step=1e-3, x_scale=np.array([1.0, 1.0, 0.01, 0.01]))
    return fit.x[:2]

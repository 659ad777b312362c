"""Intrinsics from checkerboard photographs (raw DNG files): Zhang's planar calibration.

Z. Zhang, "A flexible new technique for camera calibration", IEEE TPAMI 22(11),
1330-1334, 2000, as implemented by OpenCV's ``calibrateCamera`` (OpenCV's distortion
model [k1, k2, p1, p2, k3]; k3 held at 0 by default, as wide-angle terms are not
observable from a few boards). Corners: calibration.corners.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import rawpy

from calibration.corners import find_board_corners


@dataclass
class Calibration:
    K: np.ndarray                 # 3 x 3 camera matrix (pixels)
    dist: np.ndarray              # [k1, k2, p1, p2, k3]
    rms_px: float                 # RMS reprojection error
    found: list[str]              # files whose board was found
    missed: list[str]             # files whose board was not
    image_points: list[np.ndarray]


def board_points(inner_corners: tuple[int, int], square_size_m: float) -> np.ndarray:
    """A checkerboard's inner corners in its own frame (N, 3), metres: origin at the board's
    centre, z = 0, row by row as OpenCV's detectors list them."""
    cols, rows = inner_corners
    j, i = np.mgrid[0:rows, 0:cols]
    s = square_size_m
    return np.stack([(i - (cols - 1) / 2) * s, (j - (rows - 1) / 2) * s, np.zeros_like(i, float)], -1).reshape(-1, 3)


def raw_grey(path: str | Path) -> np.ndarray:
    """A raw file as linear grey (rawpy's black level and white balance off, no gamma),
    scaled so that its 99.5th percentile is 1."""
    with rawpy.imread(str(path)) as raw:
        rgb = raw.postprocess(gamma=(1, 1), no_auto_bright=True, use_camera_wb=False, user_wb=[1, 1, 1, 1],
                              output_bps=16, output_color=rawpy.ColorSpace.raw, demosaic_algorithm=rawpy.DemosaicAlgorithm.LINEAR)
    grey = rgb.astype(float).mean(-1) / 65535.0
    return grey / max(np.percentile(grey, 99.5), 1e-6)


def calibrate_board_views(paths, inner_corners: tuple[int, int], square_size_m: float, image_size: tuple[int, int],
                          flags: int = cv2.CALIB_FIX_K3) -> Calibration:
    """Find the board in each raw file and calibrate (needs the board in at least 3 views)."""
    cols, rows = inner_corners
    board = board_points(inner_corners, square_size_m).astype(np.float32)
    found, missed, points = [], [], []
    for path in paths:
        ok, corners = find_board_corners(raw_grey(path), inner_corners)
        (found if ok else missed).append(str(path))
        if ok:
            points.append(corners)
    if len(points) < 3:
        raise ValueError(f"the board ({cols} x {rows} inner corners) was found in {len(points)} of {len(found) + len(missed)} "
                         "views; calibration needs at least 3")
    rms, K, dist, _, _ = cv2.calibrateCamera([board] * len(points), points, image_size, None, None, flags=flags)
    return Calibration(K, dist.ravel(), float(rms), found, missed, points)


def distortion_difference_px(K: np.ndarray, dist_a, dist_b, size: tuple[int, int], covered: np.ndarray | None = None,
                             step: float = 4.0) -> float:
    """Largest distance between where two distortion models put a point, both with camera
    matrix K: every pixel of a grid over the image (or over the convex hull of
    ``covered``, pixels) is undistorted with ``dist_a`` and distorted again with ``dist_b``."""
    u, v = np.meshgrid(np.arange(0, size[0], step), np.arange(0, size[1], step))
    pixels = np.stack([u.ravel(), v.ravel()], 1).astype(float)
    if covered is not None:
        hull = cv2.convexHull(np.asarray(covered, np.float32).reshape(-1, 1, 2))
        pixels = pixels[[cv2.pointPolygonTest(hull, (float(x), float(y)), False) >= 0 for x, y in pixels]]
    rays = cv2.undistortPoints(pixels.reshape(-1, 1, 2), K, np.asarray(dist_a, float),
                               criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)).reshape(-1, 2)
    again, _ = cv2.projectPoints(np.c_[rays, np.ones(len(rays))], np.zeros(3), np.zeros(3), K, np.asarray(dist_b, float))
    return float(np.max(np.linalg.norm(again.reshape(-1, 2) - pixels, axis=1)))

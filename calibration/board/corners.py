"""Checkerboard corners in a photograph: found by OpenCV, refined by point symmetry.

Any 8/16-bit or float image, grey or colour (calibration.board.images). Detection tries, in
order, OpenCV's ``findChessboardCorners`` (about 5-10 ms on a 640 x 480 view) and then,
where it fails, ``findChessboardCornersSB`` with two flag sets (90-400 ms each here, so
only as fallbacks: trying SB first would not meet the 0.05 s per view budget). The
first detector that finds the board wins; its name and flags are reported. Corners are
listed in ``findChessboardCorners``' order (``findChessboardCornersSB`` lists them in
reverse; its lists are turned round).

OpenCV's own sub-pixel estimates, and ``cornerSubPix``'s, are biased by perspective and
weigh noisy gradients (measured on the synthetic calibration set, 640 x 480: 0.21 and
0.25 px RMS against the truth), so each corner is then moved to the centre of point
symmetry of the image around it (calibration.board.corner_refinement: 0.09 px on the same views,
0.02-0.03 px on analytically rasterized boards).

A detector asked for fewer corners than the board has finds a sub-board; the board's
border tells (calibration.board.border): the result lists the sides past which the
checker pattern goes on, and the calibration refuses such a board size.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calibration.board.border import continuing_sides, grid_is_regular
from calibration.board.corner_refinement import refine_by_symmetry
from calibration.board.images import grey_uint8, grey_unit
from workbench.core.errors import UserInputError

# (name, detector, flags): tried in this order until one finds the board. The last is the one this module used
# alone before (so nothing it found is lost); each miss costs its time (about 0.01, 0.1 and 0.4 s on a 640 x 480
# view here), so the list is short.
DETECTORS = (
    ("findChessboardCorners(ADAPTIVE_THRESH|NORMALIZE_IMAGE)", "classic",
     cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE),
    ("findChessboardCornersSB(NORMALIZE_IMAGE)", "sb", cv2.CALIB_CB_NORMALIZE_IMAGE),
    ("findChessboardCornersSB(EXHAUSTIVE|ACCURACY)", "sb", cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY),
)


@dataclass(frozen=True)
class BoardCorners:
    """What the corner finder says about one view."""

    found: bool
    corners: np.ndarray | None = None   # (cols * rows, 1, 2) float32 pixels, findChessboardCorners' order
    detector: str = ""                  # the detector and flags that found the board
    continues: tuple[str, ...] = ()     # sides of the grid past which the checker pattern goes on
    unrefined: int = 0                  # corners the symmetry fit did not trust (left at the detector's estimate)


def validate_pattern(pattern: tuple[int, int], where: str = "--board") -> tuple[int, int]:
    """(cols, rows) inner corners, each at least 2 (OpenCV's detectors need 3 x 3 squares)."""
    try:
        cols, rows = (int(n) for n in pattern)
    except (TypeError, ValueError):
        raise UserInputError("not a board size", field=where, expected="(columns, rows) of inner corners",
                             got=pattern) from None
    if cols < 2 or rows < 2:
        raise UserInputError("a checkerboard needs at least 2 x 2 inner corners", field=where, got=f"{cols}x{rows}")
    return cols, rows


def detect_board(grey8: np.ndarray, pattern: tuple[int, int]) -> tuple[np.ndarray | None, str]:
    """OpenCV's detectors in turn on an 8-bit grey image: (corners (N, 1, 2) in findChessboardCorners'
    order, detector name), or (None, "") when none finds the board."""
    for name, kind, flags in DETECTORS:
        if kind == "classic":
            ok, corners = cv2.findChessboardCorners(grey8, pattern, flags=flags)
        else:
            ok, corners = cv2.findChessboardCornersSB(grey8, pattern, flags=flags)
            if ok:
                corners = corners[::-1]
        if ok:
            return np.ascontiguousarray(corners, np.float32).reshape(-1, 1, 2), name
    return None, ""


def grid_spacing(corners: np.ndarray, pattern: tuple[int, int]) -> np.ndarray:
    """Distance (pixels) from each corner of a row-by-row grid to its nearest grid neighbour."""
    cols, rows = pattern
    grid = np.asarray(corners, float).reshape(rows, cols, 2)
    spacing = np.full((rows, cols), np.inf)
    along = np.linalg.norm(np.diff(grid, axis=1), axis=2)
    across = np.linalg.norm(np.diff(grid, axis=0), axis=2)
    spacing[:, :-1] = np.minimum(spacing[:, :-1], along)
    spacing[:, 1:] = np.minimum(spacing[:, 1:], along)
    spacing[:-1] = np.minimum(spacing[:-1], across)
    spacing[1:] = np.minimum(spacing[1:], across)
    return spacing.ravel()


def find_board_corners(image: np.ndarray, pattern: tuple[int, int]) -> BoardCorners:
    """The inner corners of a ``pattern`` = (cols, rows) checkerboard in ``image`` (any 8/16-bit
    or float array, grey (H, W) or colour (H, W, C)): detection, point-symmetry refinement,
    and the border check."""
    pattern = validate_pattern(pattern)
    grey = grey_unit(image)
    detected, detector = detect_board(grey_uint8(grey), pattern)
    if detected is None:
        return BoardCorners(False)
    if not grid_is_regular(grey, detected, pattern):
        return BoardCorners(False)   # a detector's grid that skips squares, or whose squares do not alternate
    refined, trusted = refine_by_symmetry(grey, detected.reshape(-1, 2), grid_spacing(detected, pattern))
    continues = continuing_sides(grey, refined, pattern)
    return BoardCorners(True, refined.astype(np.float32).reshape(-1, 1, 2), detector, continues, int((~trusted).sum()))

"""Is the found grid the whole board? The checker pattern must stop at the board's edge.

OpenCV's detectors, asked for fewer inner corners than a board has (8 x 5 on a 9 x 6
board), return a sub-board. A whole board ends with one ring of squares beyond its
outermost inner corners (the ring that gives those corners their four squares), and past
that ring comes the board's margin or its background: no more checker squares. So on
each side of the grid, one looks at the squares' centres in three rows parallel to that
side, predicted with a homography fitted to the three outermost lines of corners there:

* the first row of squares inside the grid (reference),
* the ring of squares just outside (part of any board: a sanity check of the geometry),
* a row a quarter of a square past that ring, which alternates in step with the checker
  parity only if the board continues (a quarter, not a half, because some printed boards
  end in narrower squares: OpenCV's 9 x 6 sample board does, and half a square past its
  sub-board's ring already falls half on the margin).

Each row's alternation is the least-squares b in value = a + b * parity (parity +-1 by
square colour), averaged over a small patch at each square's centre; the pattern
continues on that side when the row beyond has b of the same sign and at least
CONTINUATION_RATIO of the reference's. Measured on the 13 real views of OpenCV's 9 x 6
board: at most 0.22 for the whole board, 0.83-0.97 on the continuing side of an 8 x 6
sub-board. Rows that leave the image, or are too short to judge, are not judged.

Before that, the grid itself must be a checkerboard seen through a lens (``grid_is_regular``;
OpenCV's SB detector, asked for a wrong size, sometimes returns grids that skip squares):

* along every row and column, four consecutive corners have the cross-ratio of four
  equally spaced points, 4/3, which any perspective keeps (a projective invariant;
  [Hartley 2004, Sec. 2.5]), within
  MAX_CROSS_RATIO_DEVIATION (measured: at most 0.055 on the 13 real views, whose lens
  bends lines; 0.03 on synthetic boards tilted 70 degrees; skipped squares give 0.1-0.5);
* every square between the corners has its colour: sampled at the mean of its four
  corners and half-way from there to each corner, the five samples (of the image blurred by 0.08 squares) agree (their spread
  is under UNIFORM_SQUARE_SPREAD of the dark-light difference in nine squares out of
  ten; a grid that runs along the diagonals has a board corner where a square's centre
  should be), the square's median lies on the side of the squares' mean that its parity
  says, and the squares alternate by at least MIN_GRID_CONTRAST of the image's
  0.5-99.5 % range.
"""

from __future__ import annotations

import cv2
import numpy as np

CONTINUATION_RATIO = 0.5     # alternation beyond the ring, relative to the inner squares', that means "more board"
RING_RATIO = 0.3             # the ring's own alternation must reach this much of the inner squares' to judge a side
BEYOND_RING = 1.25           # squares past the outermost corners where the row beyond is sampled
MIN_SQUARES = 3              # squares in a row, inside the image, needed to judge it
PATCH_HALF_WIDTH = 0.1       # squares: the patch averaged at each square's centre
PATCH_POINTS = 5             # per axis
LINES_FOR_HOMOGRAPHY = 3
MIN_GRID_CONTRAST = 0.1      # the grid's squares alternate by at least this fraction of the image's 0.5-99.5 % range
MAX_CROSS_RATIO_DEVIATION = 0.1
UNIFORM_SQUARE_SPREAD = 0.5    # a square's five samples span at most this fraction of the dark-light difference ...
UNIFORM_SQUARE_SHARE = 0.9     # ... in at least this share of the squares (a glint or a JPEG block may spoil a few)
SAMPLE_BLUR = 0.08             # squares: the Gaussian blur (sigma) the square samples are taken through, against noise
EQUAL_SPACING_CROSS_RATIO = 4.0 / 3.0

SIDES = ("first row", "last row", "first column", "last column")


def _side_to_board(side: str, cols: int, rows: int, along: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Board coordinates (x = column, y = row, in squares) of points ``along`` a side at distance ``out`` beyond it."""
    if side == "first row":
        return np.stack([along, -out], -1)
    if side == "last row":
        return np.stack([along, rows - 1 + out], -1)
    if side == "first column":
        return np.stack([-out, along], -1)
    return np.stack([cols - 1 + out, along], -1)


def _side_homography(grid: np.ndarray, side: str) -> np.ndarray:
    """Board (column, row) to image, fitted to the three lines of corners nearest ``side``."""
    rows, cols = grid.shape[:2]
    j, i = np.mgrid[0:rows, 0:cols]
    n = LINES_FOR_HOMOGRAPHY
    pick = {"first row": j < n, "last row": j >= rows - n, "first column": i < n, "last column": i >= cols - n}[side]
    board = np.stack([i[pick], j[pick]], -1).astype(np.float32)
    H, _ = cv2.findHomography(board, grid[pick].astype(np.float32), 0)
    return H


def _row_alternation(grey: np.ndarray, H: np.ndarray, board_centres: np.ndarray) -> float | None:
    """The alternation b of value = a + b * parity over the squares centred at ``board_centres`` (M, 2), or None."""
    offsets = np.linspace(-PATCH_HALF_WIDTH, PATCH_HALF_WIDTH, PATCH_POINTS)
    dx, dy = np.meshgrid(offsets, offsets)
    patch = np.stack([dx.ravel(), dy.ravel()], -1)
    points = (board_centres[:, None, :] + patch[None]).reshape(-1, 1, 2).astype(np.float32)
    image_points = cv2.perspectiveTransform(points, H).reshape(len(board_centres), -1, 2)
    h, w = grey.shape
    inside = np.all((image_points[..., 0] >= 0) & (image_points[..., 0] <= w - 1)
                    & (image_points[..., 1] >= 0) & (image_points[..., 1] <= h - 1), axis=1)
    if inside.sum() < MIN_SQUARES:
        return None
    pts = image_points[inside].reshape(1, -1, 2).astype(np.float32)
    values = cv2.remap(grey, pts[..., 0], pts[..., 1], cv2.INTER_LINEAR).reshape(int(inside.sum()), -1).mean(axis=1)
    parity = np.where((np.floor(board_centres[inside, 0]) + np.floor(board_centres[inside, 1])) % 2 == 0, 1.0, -1.0)
    if abs(parity.sum()) == len(parity):
        return None
    design = np.stack([np.ones_like(parity), parity], -1)
    (_, b), *_ = np.linalg.lstsq(design, values, rcond=None)
    return float(b)


def continuing_sides(grey: np.ndarray, corners: np.ndarray, pattern: tuple[int, int]) -> tuple[str, ...]:
    """The sides of the found grid past which the checker pattern goes on (empty for a whole board).

    ``grey``: float image (H, W); ``corners``: (cols * rows, 2) pixels, row by row;
    ``pattern``: (cols, rows) inner corners.
    """
    cols, rows = pattern
    grid = np.asarray(corners, float).reshape(rows, cols, 2)
    image = np.ascontiguousarray(grey, np.float32)
    found = []
    for side in SIDES:
        along_count = cols if "row" in side else rows
        along = np.arange(-1, along_count) + 0.5
        H = _side_homography(grid, side)
        inner, ring, beyond = (_row_alternation(image, H, _side_to_board(side, cols, rows, along, np.full_like(along, d)))
                               for d in (-0.5, 0.5, BEYOND_RING))
        if inner is None or ring is None or beyond is None or inner == 0:
            continue
        if ring / inner < RING_RATIO:
            continue
        if beyond / inner >= CONTINUATION_RATIO:
            found.append(side)
    return tuple(found)


def _cross_ratio_deviation(grid: np.ndarray) -> float:
    """Largest |CR - 4/3| over four consecutive corners along the rows and columns of a (rows, cols, 2) grid."""
    worst = 0.0
    for lines in (grid, grid.transpose(1, 0, 2)):
        if lines.shape[1] < 4:
            continue
        p0, p1, p2, p3 = (lines[:, k:lines.shape[1] - 3 + k] for k in range(4))
        d = lambda a, b: np.linalg.norm(a - b, axis=-1)  # noqa: E731 - a distance, four times below
        ratio = d(p2, p0) * d(p3, p1) / np.maximum(d(p2, p1) * d(p3, p0), 1e-12)
        worst = max(worst, float(np.max(np.abs(ratio - EQUAL_SPACING_CROSS_RATIO))))
    return worst


def grid_is_regular(grey: np.ndarray, corners: np.ndarray, pattern: tuple[int, int]) -> bool:
    """Whether a detector's grid is a checkerboard in perspective (module docstring)."""
    cols, rows = pattern
    grid = np.asarray(corners, float).reshape(rows, cols, 2)
    if _cross_ratio_deviation(grid) > MAX_CROSS_RATIO_DEVIATION:
        return False
    quad = np.stack([grid[:-1, :-1], grid[:-1, 1:], grid[1:, 1:], grid[1:, :-1]], 2).reshape(-1, 4, 2)
    centres = quad.mean(axis=1, keepdims=True)
    points = np.concatenate([centres, (centres + quad) / 2], axis=1).reshape(1, -1, 2).astype(np.float32)  # (1, 5 n, 2)
    spacing = float(np.median(np.linalg.norm(np.diff(grid, axis=1), axis=2)))
    smooth = cv2.GaussianBlur(np.ascontiguousarray(grey, np.float32), (0, 0), max(0.5, SAMPLE_BLUR * spacing))
    samples = cv2.remap(smooth, points[..., 0], points[..., 1], cv2.INTER_LINEAR).reshape(-1, 5)
    values = np.median(samples, axis=1)
    j, i = np.mgrid[0:rows - 1, 0:cols - 1]
    parity = np.where((i + j).ravel() % 2 == 0, 1.0, -1.0)
    if abs(parity.sum()) == len(parity):
        return True   # a single square: nothing to compare
    design = np.stack([np.ones_like(parity), parity], -1)
    (_, b), *_ = np.linalg.lstsq(design, values, rcond=None)
    step = max(1, int(np.sqrt(grey.size / 20_000)))
    lo, hi = np.percentile(grey[::step, ::step], (0.5, 99.5))
    if hi <= lo or abs(b) < MIN_GRID_CONTRAST * (hi - lo):
        return False
    uniform = np.ptp(samples, axis=1) < UNIFORM_SQUARE_SPREAD * 2 * abs(b)
    if uniform.mean() < UNIFORM_SQUARE_SHARE:
        return False
    return bool(np.all((values - values.mean()) * parity * np.sign(b) > 0))

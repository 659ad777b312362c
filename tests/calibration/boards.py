"""Board views made exactly, for the calibration tests: a pinhole camera (K, no distortion)
looking at a planar board in a known pose.

* ``checkerboard_view``: each pixel the average of ``supersample``^2 samples of the
  printed pattern (dark squares, light squares and a light margin of ``margin`` squares,
  a mid-grey background beyond), so the true corners are the camera's projections of
  the board's corners;
* ``charuco_view``: OpenCV's own ChArUco image warped through the same projection at
  twice the resolution and area-averaged down.

Board frame: x along the columns, y along the rows, z = 0 on the board, corners at the
integer multiples of the square from the board's first inner corner (the checkerboard)
or from its outer corner (ChArUco, as OpenCV places it).
"""

from __future__ import annotations

import cv2
import numpy as np


def camera_matrix(f: float, size: tuple[int, int]) -> np.ndarray:
    return np.array([[f, 0, size[0] / 2 - 0.5], [0, f, size[1] / 2 - 0.5], [0, 0, 1]])


def look_at_board(tilt_x_deg: float, tilt_y_deg: float, roll_deg: float, distance: float,
                  centre: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) placing the board point ``centre`` (board units) on the optical axis at ``distance``."""
    ax, ay, az = np.radians([tilt_x_deg, tilt_y_deg, roll_deg])
    Rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    Ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    Rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    R = Rz @ Ry @ Rx
    t = np.array([0.0, 0.0, distance]) - R @ np.array([centre[0], centre[1], 0.0])
    return R, t


def board_homography(K: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Board plane (x, y) to pixels."""
    return K @ np.column_stack([R[:, 0], R[:, 1], t])


def checkerboard_view(H: np.ndarray, inner: tuple[int, int], size: tuple[int, int], supersample: int = 4,
                      margin: float = 1.0, dark: float = 0.05, light: float = 0.8, background: float = 0.3,
                      K: np.ndarray | None = None, dist: np.ndarray | None = None) -> np.ndarray:
    """The image (float, H x W) of a checkerboard of ``inner`` = (cols, rows) inner corners, squares of 1 unit;
    with ``K`` and ``dist``, seen through OpenCV's lens distortion (each sample undistorted first)."""
    cols, rows = inner
    n = supersample
    ys, xs = np.mgrid[0:size[1] * n, 0:size[0] * n]
    pix = np.stack([(xs + 0.5) / n - 0.5, (ys + 0.5) / n - 0.5, np.ones_like(xs, float)], -1)
    if dist is not None and K is not None:
        ideal = cv2.undistortPoints(pix[..., :2].reshape(-1, 1, 2), K, dist, P=K).reshape(pix.shape[:2] + (2,))
        pix = np.concatenate([ideal, np.ones(pix.shape[:2] + (1,))], -1)
    board = pix @ np.linalg.inv(H).T
    bx, by = board[..., 0] / board[..., 2], board[..., 1] / board[..., 2]
    on_board = (bx > -1 - margin) & (bx < cols + margin) & (by > -1 - margin) & (by < rows + margin) & (board[..., 2] > 0)
    in_squares = (bx > -1) & (bx < cols) & (by > -1) & (by < rows)
    is_dark = ((np.floor(bx) + np.floor(by)) % 2 == 0) & in_squares
    value = np.where(on_board, np.where(is_dark, dark, light), background)
    return value.reshape(size[1], n, size[0], n).mean(axis=(1, 3))


def true_corners(H: np.ndarray, inner: tuple[int, int]) -> np.ndarray:
    """The inner corners (cols * rows, 2) in pixels, row by row from board (0, 0)."""
    cols, rows = inner
    j, i = np.mgrid[0:rows, 0:cols]
    p = np.stack([i.ravel(), j.ravel(), np.ones(i.size)], 1) @ H.T
    return p[:, :2] / p[:, 2:]


def charuco_view(board: cv2.aruco.CharucoBoard, K: np.ndarray, R: np.ndarray, t: np.ndarray, size: tuple[int, int],
                 pixels_per_square: int = 100) -> np.ndarray:
    """An 8-bit image of ``board`` (metres) seen by (K, R, t), white paper around it, grey beyond."""
    cols, rows = board.getChessboardSize()
    square = board.getSquareLength()
    margin = pixels_per_square // 2
    printed = board.generateImage((cols * pixels_per_square + 2 * margin, rows * pixels_per_square + 2 * margin),
                                  marginSize=margin, borderBits=1)
    mpp = square / pixels_per_square
    # printed pixel (centres at integers) to board metres: the board's outer corner is the edge at margin - 0.5
    to_board = np.array([[mpp, 0, -(margin - 0.5) * mpp], [0, mpp, -(margin - 0.5) * mpp], [0, 0, 1]])
    scale = 2
    up = np.array([[scale, 0, (scale - 1) / 2], [0, scale, (scale - 1) / 2], [0, 0, 1]])  # pixel p -> 2 p + 0.5
    H = up @ board_homography(K, R, t) @ to_board
    big = cv2.warpPerspective(printed, H, (size[0] * scale, size[1] * scale), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=90)
    return cv2.resize(big, size, interpolation=cv2.INTER_AREA)

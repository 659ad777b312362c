"""ChArUco boards (OpenCV contrib's aruco module): a checkerboard whose white squares hold
ArUco markers, so every corner is identified and partial views count.

The markers: [Garrido-Jurado 2014]. OpenCV's
``CharucoDetector`` finds the markers, then interpolates and sub-pixel refines the
chessboard corners between them.

The corners are then moved to their centre of point symmetry (calibration.board.corner_refinement) over
a disc that must stay clear of the markers: the marker in a white square of side s starts
(s - m) / 2 in from each edge, so its nearest point is sqrt(2) (s - m) / 2 from the
corner; the disc's radius is MARKER_CLEARANCE of that, in pixels at the corner's local
scale (from a homography fitted to the view's corners). Below MIN_RADIUS_PX the
detector's corners are kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from calibration.board.corner_refinement import RADIUS_FACTOR, refine_by_symmetry
from calibration.board.images import grey_uint8, grey_unit
from workbench.core.errors import UserInputError

MARKER_CLEARANCE = 0.8   # of the distance from a corner to the nearest marker point
MIN_RADIUS_PX = 3.0
MIN_CORNERS = 6          # per view: a homography and a pose need more than the bare 4


@dataclass(frozen=True)
class CharucoSpec:
    dictionary: str          # OpenCV's predefined dictionary, e.g. "DICT_5X5_100"
    marker_size_m: float


@dataclass(frozen=True)
class CharucoCorners:
    found: bool
    corners: np.ndarray | None = None         # (N, 1, 2) float32 pixels
    object_points: np.ndarray | None = None   # (N, 3) float32 metres, in the board's frame
    detector: str = ""
    unrefined: int = 0


def parse_charuco(text: str, where: str = "--charuco") -> CharucoSpec:
    """'DICT,MARKER_MM' (e.g. 'DICT_5X5_100,15' or '5X5_100,15') to a CharucoSpec."""
    try:
        name, marker_mm = text.split(",")
        marker = float(marker_mm) / 1000.0
    except ValueError:
        raise UserInputError("not a ChArUco spec", field=where, expected="DICT,MARKER_MM, e.g. DICT_5X5_100,15",
                             got=text) from None
    name = name.strip().upper()
    name = name if name.startswith("DICT_") else f"DICT_{name}"
    if not isinstance(getattr(cv2.aruco, name, None), int):
        known = sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))
        raise UserInputError("unknown ArUco dictionary", field=where, expected=", ".join(known), got=name)
    if not marker > 0:
        raise UserInputError("the marker size must be positive", field=where, got=text)
    return CharucoSpec(name, marker)


def charuco_board(squares: tuple[int, int], square_size_m: float, spec: CharucoSpec) -> cv2.aruco.CharucoBoard:
    """OpenCV's board of ``squares`` = (cols, rows) squares."""
    if spec.marker_size_m >= square_size_m:
        raise UserInputError("the markers must be smaller than the squares", field="--charuco",
                             got={"marker_mm": spec.marker_size_m * 1e3, "square_mm": square_size_m * 1e3})
    if min(squares) < 2:
        raise UserInputError("a ChArUco board needs at least 2 x 2 squares", field="--board", got=squares)
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, spec.dictionary))
    markers = (squares[0] * squares[1]) // 2
    if markers > dictionary.bytesList.shape[0]:
        raise UserInputError(f"{spec.dictionary} holds {dictionary.bytesList.shape[0]} markers, the board needs "
                             f"{markers}", field="--charuco")
    return cv2.aruco.CharucoBoard(squares, square_size_m, spec.marker_size_m, dictionary)


def _local_spacing(board_xy: np.ndarray, corners: np.ndarray, square: float) -> np.ndarray | None:
    """Each corner's distance in pixels to where its board neighbours one square away fall (the nearer one)."""
    H, _ = cv2.findHomography(board_xy.astype(np.float32), corners.astype(np.float32), 0)
    if H is None:
        return None
    pts = np.concatenate([board_xy, board_xy + [square, 0], board_xy + [0, square]]).reshape(-1, 1, 2)
    image = cv2.perspectiveTransform(pts.astype(np.float64), H).reshape(3, -1, 2)
    return np.minimum(np.linalg.norm(image[1] - image[0], axis=1), np.linalg.norm(image[2] - image[0], axis=1))


def find_charuco_corners(image: np.ndarray, board: cv2.aruco.CharucoBoard) -> CharucoCorners:
    """The identified chessboard corners of a ChArUco board in ``image`` (any 8/16-bit or float, grey or colour)."""
    grey = grey_unit(image)
    detector = cv2.aruco.CharucoDetector(board)
    corners, ids, _, _ = detector.detectBoard(grey_uint8(grey))
    if corners is None or ids is None or len(ids) < MIN_CORNERS:
        return CharucoCorners(False)
    ids = ids.ravel()
    if board.checkCharucoCornersCollinear(ids.reshape(-1, 1)):
        return CharucoCorners(False)
    object_points = np.asarray(board.getChessboardCorners(), np.float32)[ids]
    corners = corners.reshape(-1, 2).astype(float)
    square, marker = board.getSquareLength(), board.getMarkerLength()
    factor = min(RADIUS_FACTOR, MARKER_CLEARANCE * np.sqrt(2.0) * (square - marker) / (2.0 * square))
    spacing = _local_spacing(object_points[:, :2].astype(float), corners, square)
    unrefined = len(corners)
    if spacing is not None and np.median(factor * spacing) >= MIN_RADIUS_PX:
        corners, trusted = refine_by_symmetry(grey, corners, spacing, radius_factor=factor)
        unrefined = int((~trusted).sum())
    return CharucoCorners(True, corners.astype(np.float32).reshape(-1, 1, 2), object_points,
                          "CharucoDetector", unrefined)

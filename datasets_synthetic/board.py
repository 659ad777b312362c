"""A checkerboard calibration target: its texture, its Mitsuba shape, the poses a
photographer holds it in, and its corner coordinates.

Planar-target calibration (Z. Zhang, "A flexible new technique for camera calibration",
IEEE TPAMI 22(11), 1330-1334, 2000, Sec. 2-3) needs the board seen in several
orientations: each view gives a homography, two constraints on the intrinsics, so
tilted views (not only fronto-parallel ones) make the focal lengths observable. The
poses here are drawn like that: the board filling about half the frame, tilted by up
to ~35 degrees about both of its axes, rolled a little, held inside the box and in
front of everything in it (checked by tracing rays to its corners), and turned towards the light so that it is lit.

Board frame: origin at the board's centre, x along a row of squares, y along a column,
z the board's normal towards the viewer; the inner corners lie at z = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

BOARD_KEY = "calibration_board"
BOX_INTERIOR_M = ((0.005, 0.551), (0.05, 0.54), (-0.25, 0.55))  # x, y, z the board stays in (m): above the glass, at most 25 cm out of the open front


@dataclass(frozen=True)
class Checkerboard:
    inner_corners: tuple[int, int] = (9, 6)   # (cols, rows), OpenCV's patternSize
    square_size_m: float = 0.030
    margin_squares: float = 1.0               # white border around the squares (the detector's quiet zone)
    texels_per_square: int = 16
    black: float = 0.04                        # diffuse reflectances of the printed board
    white: float = 0.80

    @property
    def squares(self) -> tuple[int, int]:
        return self.inner_corners[0] + 1, self.inner_corners[1] + 1

    @property
    def size_m(self) -> tuple[float, float]:
        """Width and height of the whole board, margin included."""
        cols, rows = self.squares
        return ((cols + 2 * self.margin_squares) * self.square_size_m, (rows + 2 * self.margin_squares) * self.square_size_m)

    def to_json(self) -> dict:
        return {"type": "checkerboard", "inner_corners": list(self.inner_corners), "square_size_m": self.square_size_m,
                "size_m": list(self.size_m), "reflectance_black": self.black, "reflectance_white": self.white}

    def texture(self) -> np.ndarray:
        """The printed pattern as linear reflectance, (H, W, 3) float32, squares on texel boundaries."""
        t = self.texels_per_square
        cols, rows = self.squares
        margin = int(round(self.margin_squares * t))
        iy, ix = np.mgrid[0:rows * t, 0:cols * t] // t
        pattern = np.where((ix + iy) % 2 == 0, self.black, self.white)
        image = np.pad(pattern, margin, constant_values=self.white)
        return np.repeat(image[:, :, None], 3, axis=2).astype(np.float32)

    def object_points(self) -> np.ndarray:
        """Inner corners in the board frame (N, 3), row by row as OpenCV's detectors list them."""
        cols, rows = self.inner_corners
        s = self.square_size_m
        j, i = np.mgrid[0:rows, 0:cols]
        return np.stack([(i - (cols - 1) / 2) * s, (j - (rows - 1) / 2) * s, np.zeros_like(i, float)], -1).reshape(-1, 3)

    def outline(self) -> np.ndarray:
        """The board's four outer corners in its frame (4, 3)."""
        w, h = self.size_m
        return np.array([[-w / 2, -h / 2, 0], [w / 2, -h / 2, 0], [w / 2, h / 2, 0], [-w / 2, h / 2, 0]])

    def shape_matrix(self, board_to_world: np.ndarray) -> np.ndarray:
        """Mitsuba's rectangle spans [-1, 1]^2: scale it to the board's size, then place it."""
        w, h = self.size_m
        return np.asarray(board_to_world, float) @ np.diag([w / 2, h / 2, 1.0, 1.0])

    def mitsuba_shape(self, mi, board_to_world: np.ndarray) -> dict:
        return {"type": "rectangle", "to_world": mi.ScalarTransform4f(self.shape_matrix(board_to_world).tolist()),
                "bsdf": {"type": "diffuse", "reflectance": {"type": "bitmap", "bitmap": mi.Bitmap(self.texture()),
                                                            "raw": False, "filter_type": "nearest"}}}


def _held_pose(camera, pixel: tuple[float, float], distance: float, tilt_deg: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Board-to-world: centre on the ray through ``pixel`` at ``distance``, turned halfway
    between the camera and the light (so that the light falls on its face, as a
    photographer holds it), then tilted by (about x, about y, roll) in its own frame."""
    import cv2

    ray = camera.normalized(np.array([pixel], float)).reshape(2)
    cam_to_world = np.linalg.inv(camera.world_to_camera)
    direction = cam_to_world[:3, :3] @ np.array([ray[0], ray[1], 1.0])
    direction /= np.linalg.norm(direction)
    centre = cam_to_world[:3, 3] + distance * direction
    to_light = (light - centre) / np.linalg.norm(light - centre)
    z = to_light - direction
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z]) @ Rotation.from_euler("xyz", tilt_deg, degrees=True).as_matrix()
    T[:3, 3] = centre
    return T


def _inside(board: Checkerboard, board_to_world: np.ndarray, camera, margin_px: float = 4.0) -> bool:
    """The whole board is in the frame, and none of it is inside the box's walls, floor or
    ceiling or near the objects on its floor (a grid of points on the board is checked;
    out of the open front, z < 0, it may hang below the floor's level)."""
    w, h = board.size_m
    u, v = np.meshgrid(np.linspace(-w / 2, w / 2, 13), np.linspace(-h / 2, h / 2, 10))
    local = np.stack([u.ravel(), v.ravel(), np.zeros(u.size), np.ones(u.size)])
    x, y, z = (board_to_world @ local)[:3]
    (x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi) = BOX_INTERIOR_M
    in_box = z > -0.005
    if np.any(z < z_lo) or np.any(z > z_hi) or np.any(y > y_hi):
        return False
    if np.any(in_box & ((x < x_lo) | (x > x_hi) | (y < y_lo))):
        return False
    pix = camera.project((board_to_world @ np.c_[board.outline(), np.ones(4)].T).T[:, :3])
    return bool(np.all(pix >= margin_px) and np.all(pix[:, 0] <= camera.width - 1 - margin_px)
                and np.all(pix[:, 1] <= camera.height - 1 - margin_px))


def _well_seen_and_lit(pose: np.ndarray, camera, light: np.ndarray) -> bool:
    """The detector needs the squares seen within 60 degrees of face-on (cos >= 0.5),
    and the board needs the light within ~80 degrees of its normal (cos >= 0.2) to be
    bright enough."""
    normal, centre = pose[:3, 2], pose[:3, 3]
    to_camera = np.linalg.inv(camera.world_to_camera)[:3, 3] - centre
    to_light = light - centre
    return bool(normal @ to_camera >= 0.5 * np.linalg.norm(to_camera) and normal @ to_light >= 0.2 * np.linalg.norm(to_light))


def sample_pose(board: Checkerboard, camera, light, rng: np.random.Generator, view: int = 0,
                attempts: int = 5000) -> np.ndarray:
    """A seeded board pose, lit by ``light`` (a point, world metres), inside the box and the
    frame. As a photographer covers the frame for a calibration: view ``view`` puts the
    board in cell ``view % 9`` of a 3 x 3 grid over the image, filling 40-55 % of its
    width in the corner cells (where distortion is strongest) and 55-85 % elsewhere, tilted by 30-45 degrees towards a direction that turns by 137.5 degrees from one
    view to the next (so that any few views tilt different ways), rolled a little. Where
    the box does not fit the board in that cell (near the floor), any cell will do, and
    then any tilt direction."""
    for attempt in range(attempts):
        cell_u, cell_v = (view % 3, (view // 3) % 3) if attempt < attempts // 3 else rng.integers(0, 3, 2)
        turn = math.radians(137.5 * view) if attempt < 2 * attempts // 3 else rng.uniform(0, 2 * math.pi)
        corner_cell = cell_u != 1 and cell_v != 1
        fraction = rng.uniform(0.40, 0.55) if corner_cell else rng.uniform(0.55, 0.85)
        distance = camera.fx * board.size_m[0] / (fraction * camera.width)
        pixel = ((0.2 + 0.3 * cell_u + rng.uniform(-0.08, 0.08)) * camera.width,
                 (0.2 + 0.3 * cell_v + rng.uniform(-0.08, 0.08)) * camera.height)
        tilt = rng.uniform(30, 45)
        angles = np.array([tilt * math.cos(turn), tilt * math.sin(turn), rng.uniform(-10, 10)]) + rng.normal(0, 3, 3)
        pose = _held_pose(camera, pixel, distance, angles, np.asarray(light, float))
        if not _well_seen_and_lit(pose, camera, np.asarray(light, float)):
            continue
        if _inside(board, pose, camera):
            return pose
    raise RuntimeError(f"no board pose found in {attempts} attempts: the camera does not see enough of the box interior")


def corners_visible(mi, scene, board: Checkerboard, board_to_world: np.ndarray, camera) -> bool:
    """Nothing in the scene hides a corner of the board (rays from the camera centre, Mitsuba's ray_test)."""
    points = np.vstack([board.object_points(), board.outline()])
    world = (board_to_world @ np.c_[points, np.ones(len(points))].T).T[:, :3]
    origin = np.linalg.inv(camera.world_to_camera)[:3, 3]
    d = world - origin
    dist = np.linalg.norm(d, axis=1)
    d /= dist[:, None]
    ray = mi.Ray3f(mi.Point3f(*[np.full(len(d), o) for o in origin]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
    ray.maxt = mi.Float(dist * (1 - 1e-4))
    return not bool(np.any(np.array(scene.ray_test(ray))))

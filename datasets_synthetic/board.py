"""A checkerboard calibration target: its texture, its Mitsuba shape, the poses a
photographer holds it in, and its corner coordinates.

Planar-target calibration ([Zhang 2000, Secs. 2-3]) needs the board seen in several
orientations: each view gives a homography, two constraints on the intrinsics, so
tilted views (not only fronto-parallel ones) make the focal lengths observable, and
the principal point needs tilts in every direction (tilts all one way leave it
correlated with the poses), and the lens distortion needs the board out at the image's
edges and corners. The poses here are drawn like that (``sample_pose``): the board
filling 50-90 % of the frame's width, pushed into the image corners and against its
edges, its face turned 30-45 degrees from the line of sight in directions all round,
rolled a little, held inside the box and in front of everything in it (checked by
tracing rays to its corners). The camera's flash lights it (synth.py), so any
direction facing the camera is lit; the box's ceiling light alone lit only faces turned
up towards it, which left cy twice as uncertain (0.8-1.1 % against 0.4 % at one
standard deviation, for 0.05 px of corner noise at 320 x 240, from
cv2.calibrateCameraExtended on the sampled poses of five seeds).

Board frame: origin at the board's centre, x along a row of squares, y along a column,
z the board's normal towards the viewer; the inner corners lie at z = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

BOARD_KEY = "calibration_board"
# x, y, z the board stays in (m): above the glass, at most 25 cm out of the open front
BOX_INTERIOR_M = ((0.005, 0.551), (0.05, 0.54), (-0.25, 0.55))


@dataclass(frozen=True)
class Checkerboard:
    inner_corners: tuple[int, int] = (9, 6)   # (cols, rows), OpenCV's patternSize
    square_size_m: float = 0.020              # 24 x 18 cm with the margin: fits into the image corners inside the box
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
        """Inner corners in the board frame (N, 3), metres, row by row (x fastest).

        Worked out here from the printed squares (the truth must not come from the
        calibration code it checks): the squares span ``cols * s`` by ``rows * s`` about
        the board's centre, and inner corner (k, l) is where squares k-1, k and l-1, l
        meet, at x = -cols s / 2 + k s, y = -rows s / 2 + l s, for k = 1 .. cols - 1 and
        l = 1 .. rows - 1. tests/datasets_synthetic/test_board.py checks this against
        calibration's own board model.
        """
        cols, rows = self.squares
        s = self.square_size_m
        xs = -cols * s / 2 + s * np.arange(1, cols)
        ys = -rows * s / 2 + s * np.arange(1, rows)
        return np.array([[x, y, 0.0] for y in ys for x in xs])

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


def _held_pose(camera, pixel: tuple[float, float], distance: float, tilt_deg: float, towards_deg: float,
               roll_deg: float) -> np.ndarray:
    """Board-to-world: centre on the ray through ``pixel`` at ``distance``; its face turned
    away from the line of sight by ``tilt_deg``, towards ``towards_deg`` around it (0: the
    face turned up, to the image's top; 90: to its right); its rows along the camera's x
    axis, then rolled by ``roll_deg`` about its normal."""
    ray = camera.normalized(np.array([pixel], float)).reshape(2)
    cam_to_world = np.linalg.inv(camera.world_to_camera)
    direction = cam_to_world[:3, :3] @ np.array([ray[0], ray[1], 1.0])
    direction /= np.linalg.norm(direction)
    centre = cam_to_world[:3, 3] + distance * direction
    to_camera = -direction
    up = -cam_to_world[:3, 1] + (cam_to_world[:3, 1] @ to_camera) * to_camera  # the image's up, across the line of sight
    up /= np.linalg.norm(up)
    right = np.cross(up, to_camera)
    t, a = math.radians(tilt_deg), math.radians(towards_deg)
    z = math.cos(t) * to_camera + math.sin(t) * (math.cos(a) * up + math.sin(a) * right)
    x = cam_to_world[:3, 0] - (cam_to_world[:3, 0] @ z) * z
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z]) @ Rotation.from_rotvec([0.0, 0.0, math.radians(roll_deg)]).as_matrix()
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
    box = _outline_box(board, board_to_world, camera)
    return bool(np.all(box[:2] >= margin_px) and box[2] <= camera.width - 1 - margin_px
                and box[3] <= camera.height - 1 - margin_px)


def _well_seen(pose: np.ndarray, camera) -> bool:
    """The detector needs the squares seen within 60 degrees of face-on (cos >= 0.5); the
    flash at the camera then lights the board at least half as well as face-on."""
    normal, centre = pose[:3, 2], pose[:3, 3]
    to_camera = np.linalg.inv(camera.world_to_camera)[:3, 3] - centre
    return bool(normal @ to_camera >= 0.5 * np.linalg.norm(to_camera))


def _outline_box(board: Checkerboard, pose: np.ndarray, camera) -> np.ndarray:
    """Pixel bounding box (u_min, v_min, u_max, v_max) of the board's outline in the image."""
    pix = camera.project((pose @ np.c_[board.outline(), np.ones(4)].T).T[:, :3])
    return np.concatenate([pix.min(0), pix.max(0)])


GOLDEN_TURN = (3.0 - math.sqrt(5.0)) / 2.0  # the golden angle as a fraction of a turn (137.5 degrees)


def sample_pose(board: Checkerboard, camera, rng: np.random.Generator, view: int = 0,
                attempts: int = 3000, margin_px: float = 4.0) -> np.ndarray:
    """A seeded board pose inside the box and the frame, facing the camera. As a
    photographer covers the frame for a calibration: view ``view`` aims at cell
    ``view % 9`` of a 3 x 3 grid over the image and pushes the board against that cell's
    image borders (a corner cell puts it into that image corner, an edge cell against
    that edge, the middle cell leaves it near the centre), filling 50-70 % of the width
    in the corner cells and 65-90 % elsewhere; its face is turned 30-45 degrees from the
    line of sight, towards a direction that turns by the golden angle from one view to
    the next (so that any few views tilt different ways, all round), and rolled a
    little. Where the box does not fit the board so tilted in that cell, any tilt
    direction will do, and then any cell."""
    size = np.array([camera.width, camera.height], float)
    for attempt in range(attempts):
        cell = np.array([view % 3, (view // 3) % 3]) if attempt < 2 * attempts // 3 else rng.integers(0, 3, 2)
        if attempt < attempts // 3:
            towards = 360.0 * ((view * GOLDEN_TURN) % 1.0) + rng.normal(0.0, 5.0)
        else:
            towards = rng.uniform(0.0, 360.0)
        corner_cell = cell[0] != 1 and cell[1] != 1
        fraction = rng.uniform(0.50, 0.70) if corner_cell else rng.uniform(0.65, 0.90)
        distance = camera.fx * board.size_m[0] / (fraction * camera.width)
        pixel = (0.5 + 0.3 * (cell - 1) + rng.uniform(-0.08, 0.08, 2)) * size
        tilt, roll = rng.uniform(30.0, 45.0), rng.uniform(-10.0, 10.0)
        # Against the borders: where the cell is at an edge of the grid, move the board
        # along the image until its outline is a few pixels from that edge (the pose
        # turns a little with the centre's ray, hence a few rounds).
        gap = margin_px + rng.uniform(0.0, 6.0, 2)
        for _ in range(4):
            pose = _held_pose(camera, tuple(pixel), distance, tilt, towards, roll)
            box = _outline_box(board, pose, camera)
            shift = np.zeros(2)
            for k in range(2):
                if cell[k] == 0:
                    shift[k] = gap[k] - box[k]
                elif cell[k] == 2:
                    shift[k] = size[k] - 1 - gap[k] - box[2 + k]
            if np.all(np.abs(shift) < 0.5):
                break
            pixel = pixel + shift
        if _well_seen(pose, camera) and _inside(board, pose, camera, margin_px):
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

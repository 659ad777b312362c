"""What calibration knows of a scene's geometry: edges to align with, and what hides them.

Built from a renderer.scene.SceneSpec with the renderer's placement of the objects
(renderer.placement, the one definition the Mitsuba scene uses too):
the measured Cornell box (renderer/data/cornell_box.json, mm, scaled to metres and by
``box.size``), the ceiling light rectangle, the CDs (annuli, a polycarbonate top 1.2 mm
above the grating) and the glass cube and sphere.

Features (known 3D curves whose image is an intensity edge in a photograph):

* the box's edges: the creases where two walls meet and the open front's outline
  (each quad's sides, shared sides once);
* the light rectangle's four sides (the brightest edge in the scene);
* each CD's outer rim (a 3D circle, projected to an ellipse) on its top face.

Occluders (what hides a feature point from a camera): the box's own quads, the glass
objects (a cube's 12 triangles, a sphere) and the CDs' discs. A point is visible when the
segment from the camera centre to it meets none of them (ray-triangle test of T. Möller
and B. Trumbore, "Fast, minimum storage ray-triangle intersection", J. Graphics Tools
2(1), 1997; ray-sphere in closed form; discs, the box's walls and the light's rectangle
from renderer.trace.geometry).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from renderer.placement import cd_top_center, cube_to_world
from renderer.scene import SceneSpec
from renderer.trace.geometry import annulus_hits, box_walls, light_corners

OCCLUSION_EPS_M = 2e-4  # a point on a surface is not hidden by that surface (nor by a neighbour within this)


@dataclass(frozen=True)
class Segment:
    """A straight 3D edge from ``a`` to ``b`` (metres), e.g. ``floor_white|back_wall_white``."""

    name: str
    a: np.ndarray
    b: np.ndarray


@dataclass(frozen=True)
class Circle:
    """A 3D circle: centre, unit normal and radius (metres), e.g. a CD's rim."""

    name: str
    center: np.ndarray
    normal: np.ndarray
    radius: float

    def points(self, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (N, 3) and unit tangents (N, 3) at ``angles`` (radians)."""
        u, w = _orthonormal_pair(self.normal)
        c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
        return self.center + self.radius * (c * u + s * w), -s * u + c * w


@dataclass(frozen=True)
class Occluders:
    triangles: np.ndarray                                   # (M, 3, 3)
    spheres: tuple[tuple[np.ndarray, float], ...] = ()      # (centre, radius)
    discs: tuple[tuple[np.ndarray, np.ndarray, float, float], ...] = ()  # (centre, normal, inner, outer)


@dataclass(frozen=True)
class SceneModel:
    segments: tuple[Segment, ...]
    circles: tuple[Circle, ...]
    occluders: Occluders
    walls: dict[str, np.ndarray] = field(default_factory=dict)  # the box's quads (4, 3) by name
    light_corners: np.ndarray = field(default_factory=lambda: np.zeros((4, 3)))
    glass: tuple[tuple[str, np.ndarray, float, float], ...] = ()  # (shape, centre, size or radius, rotation_deg)
    cd_bases: tuple[np.ndarray, ...] = ()                      # each CD's grating centre (its rim circle is on the top)


def _orthonormal_pair(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def _quad_segments(walls: dict[str, np.ndarray]) -> list[Segment]:
    """Each quad side once; a side two quads share is named after both (a crease)."""
    found: dict[tuple, list] = {}
    for name, quad in walls.items():
        for i in range(4):
            a, b = quad[i], quad[(i + 1) % 4]
            key = tuple(sorted([tuple(np.round(a, 7)), tuple(np.round(b, 7))]))
            if key in found:
                found[key][2].append(name)
            else:
                found[key] = [a, b, [name]]
    return [Segment("|".join(names), a, b) for a, b, names in found.values()]


def _cube_triangles(center: np.ndarray, size: float, rotation_deg: float) -> np.ndarray:
    """A glass cube's 12 triangles where the renderer places it (renderer.placement.cube_to_world)."""
    to_world = cube_to_world(center, size, rotation_deg)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)  # Mitsuba's cube
    corners = corners @ to_world[:3, :3].T + to_world[:3, 3]
    faces = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    return np.array([[corners[f[0]], corners[f[i]], corners[f[i + 1]]] for f in faces for i in (1, 2)])


def scene_model(spec: SceneSpec) -> SceneModel:
    """The features and occluders of ``spec`` (see the module docstring)."""
    walls = box_walls(spec)
    light = light_corners(spec)
    segments = _quad_segments(walls) + [Segment(f"light.{i}", light[i], light[(i + 1) % 4]) for i in range(4)]
    triangles = [np.array([q[0], q[1], q[2]]) for q in walls.values()] + [np.array([q[0], q[2], q[3]]) for q in walls.values()]
    circles, discs, spheres, glass, bases = [], [], [], [], []
    for i, cd in enumerate(spec.cds):
        normal = np.asarray(cd.normal, float)
        base = np.asarray(cd.center, float)
        top = cd_top_center(cd) if cd.top_surface else base
        circles.append(Circle(f"cd[{i}].rim", top, normal, cd.outer_radius))
        bases.append(base)
        discs += [(base, normal, cd.inner_radius, cd.outer_radius), (top, normal, cd.inner_radius, cd.outer_radius)]
    for g in spec.glass:
        center = np.asarray(g.center, float)
        if g.shape == "sphere":
            spheres.append((center, g.size))
        else:
            triangles += list(_cube_triangles(center, g.size, g.rotation_deg))
        glass.append((g.shape, center, g.size, g.rotation_deg))
    return SceneModel(tuple(segments), tuple(circles), Occluders(np.array(triangles), tuple(spheres), tuple(discs)),
                      walls, light, tuple(glass), tuple(bases))


def visible(points: np.ndarray, eye: np.ndarray, occluders: Occluders) -> np.ndarray:
    """Which of ``points`` (N, 3) the camera centre ``eye`` sees: nothing between them."""
    points = np.asarray(points, float)
    direction = points - eye
    length = np.linalg.norm(direction, axis=1)
    d = direction / length[:, None]
    limit = length - OCCLUSION_EPS_M
    hidden = np.zeros(len(points), bool)
    for tri in occluders.triangles:
        hidden |= _hits_triangle(eye, d, tri, limit)
    for center, radius in occluders.spheres:
        hidden |= _hits_sphere(eye, d, center, radius, limit)
    for center, normal, inner, outer in occluders.discs:
        hidden |= annulus_hits(eye, d, center, normal, inner, outer, 1e-9, limit)
    return ~hidden


def _hits_triangle(origin: np.ndarray, d: np.ndarray, tri: np.ndarray, limit: np.ndarray) -> np.ndarray:
    e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
    p = np.cross(d, e2)
    det = p @ e1
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origin - tri[0]
    u = (p @ s) * inv
    q = np.cross(s, e1)
    v = (d @ q) * inv
    t = (q @ e2) * inv
    return ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9) & (t < limit)


def _hits_sphere(origin: np.ndarray, d: np.ndarray, center: np.ndarray, radius: float, limit: np.ndarray) -> np.ndarray:
    oc = origin - center
    b = d @ oc
    disc = b * b - (oc @ oc - radius * radius)
    root = np.sqrt(np.maximum(disc, 0.0))
    t_near = -b - root
    return (disc > 0) & (t_near > 1e-9) & (t_near < limit)


@dataclass(frozen=True)
class FeatureSamples:
    """3D points on the features, with unit tangents and the index of their feature."""

    points: np.ndarray    # (N, 3)
    tangents: np.ndarray  # (N, 3)
    feature: np.ndarray   # (N,) index into ``names``
    names: tuple[str, ...]

    def subset(self, keep: np.ndarray) -> FeatureSamples:
        return FeatureSamples(self.points[keep], self.tangents[keep], self.feature[keep], self.names)


def sample_features(model: SceneModel, camera, spacing_px: float, margin_px: float = 0.0,
                    end_clearance_px: float = 4.0, occluder_margin_px: float = 0.0) -> FeatureSamples:
    """Points every ``spacing_px`` (in ``camera``'s image) along every feature that the camera
    sees: in front of it, inside the image by ``margin_px``, not hidden (``visible``), and at
    least ``end_clearance_px`` from a segment's ends (corners, where two edges blur together),
    and, with ``occluder_margin_px``, that far from the outline of a glass object or of a CD
    the feature does not belong to."""
    points, tangents, feature = [], [], []
    names = [s.name for s in model.segments] + [c.name for c in model.circles]
    rotation, translation = camera.world_to_camera[:3, :3], camera.world_to_camera[:3, 3]
    f = max(camera.fx, camera.fy)
    for k, seg in enumerate(model.segments):
        ends_cam = np.stack([seg.a, seg.b]) @ rotation.T + translation
        depth = max(min(ends_cam[:, 2]), 1e-3)
        length_px = np.linalg.norm(seg.b - seg.a) * f / depth
        n = max(int(length_px / spacing_px), 2)
        clear = min(end_clearance_px / max(length_px, 1e-9), 0.45)
        t = np.linspace(clear, 1 - clear, n)
        direction = (seg.b - seg.a) / np.linalg.norm(seg.b - seg.a)
        points.append(seg.a + t[:, None] * (seg.b - seg.a))
        tangents.append(np.repeat(direction[None], n, 0))
        feature.append(np.full(n, k))
    for j, circle in enumerate(model.circles):
        depth = max(float((circle.center @ rotation.T + translation)[2]), 1e-3)
        n = max(int(2 * np.pi * circle.radius * f / depth / spacing_px), 8)
        p, tg = circle.points(np.linspace(0, 2 * np.pi, n, endpoint=False))
        points.append(p)
        tangents.append(tg)
        feature.append(np.full(n, len(model.segments) + j))
    samples = FeatureSamples(np.concatenate(points), np.concatenate(tangents), np.concatenate(feature), tuple(names))
    cam = samples.points @ rotation.T + translation
    ahead = cam[:, 2] > 1e-3
    pixels = camera.project(samples.points)
    inside = ahead & (pixels[:, 0] >= margin_px) & (pixels[:, 0] <= camera.width - 1 - margin_px) & \
        (pixels[:, 1] >= margin_px) & (pixels[:, 1] <= camera.height - 1 - margin_px)
    eye = -rotation.T @ translation
    keep = inside.copy()
    keep[inside] = visible(samples.points[inside], eye, model.occluders)
    if occluder_margin_px > 0:
        keep &= ~_near_occluders(model, camera, samples, pixels, occluder_margin_px)
    return samples.subset(keep)


def _near_occluders(model: SceneModel, camera, samples: FeatureSamples, pixels: np.ndarray, margin_px: float) -> np.ndarray:
    """Samples whose image lies within ``margin_px`` of a glass object's or another CD's
    outline: refraction and the objects' own edges disturb the edge there."""
    h, w = camera.height, camera.width
    near = np.zeros(len(pixels), bool)
    size = int(2 * math.ceil(margin_px) + 1)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    inside = np.all(np.isfinite(pixels), 1) & (pixels[:, 0] >= 0) & (pixels[:, 0] < w) & (pixels[:, 1] >= 0) & (pixels[:, 1] < h)
    cols = np.clip(np.rint(pixels[:, 0]), 0, w - 1).astype(int)
    rows = np.clip(np.rint(pixels[:, 1]), 0, h - 1).astype(int)
    for owner, outline in _outlines(model):
        mask = np.zeros((h, w), np.uint8)
        hull = _projected_hull(camera, outline)
        if hull is None:
            continue
        cv2.fillConvexPoly(mask, hull, 255)
        mask = cv2.dilate(mask, kernel)
        own = np.array([samples.names[k].startswith(owner) for k in samples.feature]) if owner else np.zeros(len(pixels), bool)
        near |= inside & (mask[rows, cols] > 0) & ~own
    return near


def _outlines(model: SceneModel) -> list[tuple[str, np.ndarray]]:
    """3D points whose projected convex hull covers each occluder: (owner feature prefix, points)."""
    out: list[tuple[str, np.ndarray]] = []
    for shape, center, size, rotation in model.glass:
        if shape == "sphere":
            d = np.random.default_rng(0).normal(size=(400, 3))
            out.append(("", center + size * d / np.linalg.norm(d, axis=1, keepdims=True)))
        else:
            out.append(("", _cube_triangles(center, size, rotation).reshape(-1, 3)))
    for i, circle in enumerate(model.circles):
        p, _ = circle.points(np.linspace(0, 2 * np.pi, 90, endpoint=False))
        below = p - (circle.center - model.cd_bases[i]) if i < len(model.cd_bases) else p
        out.append((circle.name.split(".")[0], np.concatenate([p, below])))
    return out


def _projected_hull(camera, points: np.ndarray) -> np.ndarray | None:
    cam = points @ camera.world_to_camera[:3, :3].T + camera.world_to_camera[:3, 3]
    if np.any(cam[:, 2] <= 1e-3):
        return None
    pixels = camera.project(points)
    return cv2.convexHull(np.rint(pixels).astype(np.int32))


def occluder_mask(model: SceneModel, camera, margin_px: float) -> np.ndarray:
    """Pixels (bool, H x W) within ``margin_px`` of a glass object or a CD, or on the light."""
    mask = np.zeros((camera.height, camera.width), np.uint8)
    for _, outline in _outlines(model) + [("", model.light_corners)]:
        hull = _projected_hull(camera, outline)
        if hull is not None:
            cv2.fillConvexPoly(mask, hull, 255)
    size = int(2 * math.ceil(margin_px) + 1)
    return cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))) > 0

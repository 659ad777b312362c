"""What else makes an edge beside the CD's rim in an image: the CD's own shadow on the floor.
A rim search leaves the points where its border is in reach out.

A CD standing on the floor casts a shadow that touches its rim where the disc is low. There
the strongest brightness gradient along the rim's normal is the shadow's edge on the floor,
a few pixels outside the disc, not the disc's edge (measured on a synthetic photo with
the true camera: rim points 3-5 px outward along a quarter of the rim). This module tells,
for each point of a rim search, whether the search's outer half crosses the border of a
shadow: the pixels outside the rim are cast into the box (the first wall plane hit, inside
that wall's extent), and each hit point is tested against a grid of points on the ceiling
light for a segment that crosses the CD's annulus. A point whose lit fraction changes
along the search has a shadow edge in reach and is left out.

Not handled: where the disc is brighter than what lies beyond it (the light's band reaching
the rim), the polycarbonate top's edge shows as a thin bright ring outside the grating's and
the strongest gradient is that ring's outer side (measured: 0.3-0.7 px out by sector on the
far, tilt-sensitive arc, 1.3-1.5 px where the band meets the rim). Keeping only points where
the disc is darker than the background removed that bias but also most of the far arc, and
the tilt fitted worse (1.4 deg of 2 became 0.5 deg), so those points stay.

Geometry: ray-plane intersections in closed form (renderer.trace.geometry.ray_plane_t,
[Pharr 2023, Sec. 6.1.2]); the light is the scene file's rectangle
(renderer.trace.geometry.LightRectangle).
"""

from __future__ import annotations

import numpy as np

from renderer.camera import CameraModel
from renderer.trace.geometry import box_walls, light_rectangle, ray_plane_t
from renderer.trace.prediction import CDGeometry
from reports.fringes.rim import outward_normals

LIGHT_GRID = 4  # light samples per side (16 in all): the penumbra's lit fraction to 1/16
SHADOW_STEP_PX = 0.5  # spacing of the tested pixels along a search
LIT_CHANGE = 0.05  # a lit fraction varying by more than this along a search: a shadow edge in reach
WALL_MARGIN_M = 0.01  # a wall's hit counts within its bounding box grown by this


def light_samples(spec, grid: int = LIGHT_GRID) -> np.ndarray:
    """Points (grid**2, 3) spread evenly over the light rectangle (cell centres)."""
    return light_rectangle(spec).grid(grid)


def first_wall_hits(spec, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """The nearest point (N, 3) where each ray meets a wall of the box (NaN where none)."""
    best_t = np.full(len(directions), np.inf)
    for quad in box_walls(spec).values():
        normal = np.cross(quad[1] - quad[0], quad[2] - quad[0])
        normal /= np.linalg.norm(normal)
        t = ray_plane_t(origin, directions, quad[0], normal)
        with np.errstate(invalid="ignore"):
            hit = origin + t[:, None] * directions
        lo, hi = quad.min(axis=0) - WALL_MARGIN_M, quad.max(axis=0) + WALL_MARGIN_M
        inside = np.all((hit >= lo) & (hit <= hi), axis=1) & (t > 0) & np.isfinite(t)
        best_t = np.where(inside & (t < best_t), t, best_t)
    found = np.isfinite(best_t)
    hits = np.full(directions.shape, np.nan)
    hits[found] = origin + best_t[found, None] * directions[found]
    return hits


def lit_fraction(points: np.ndarray, lights: np.ndarray, cd: CDGeometry) -> np.ndarray:
    """The share (N,) of ``lights`` that each point sees past the CD's annulus."""
    normal = cd.normal
    to_light = lights[None, :, :] - points[:, None, :]  # (N, L, 3)
    t = ray_plane_t(points[:, None, :], to_light, cd.center, normal)
    hit = points[:, None, :] + t[..., None] * to_light
    radius = np.linalg.norm(hit - cd.center, axis=2)
    blocked = (t > 1e-6) & (t < 1.0) & (radius >= cd.inner_radius) & (radius <= cd.outer_radius)
    return 1.0 - blocked.mean(axis=1)


def shadow_in_reach(spec, camera: CameraModel, cd: CDGeometry, expected: np.ndarray, search_px: float) -> np.ndarray:
    """For each point of the expected rim (pixels (N, 2), a closed curve), whether a border of the
    CD's shadow lies within ``search_px`` outside it (bool (N,))."""
    outward = outward_normals(expected)
    steps = np.arange(SHADOW_STEP_PX, search_px + SHADOW_STEP_PX, SHADOW_STEP_PX)
    pixels = (expected[:, None, :] + steps[None, :, None] * outward[:, None, :]).reshape(-1, 2)
    origin, directions = camera.pixel_rays(pixels)
    hits = first_wall_hits(spec, origin, directions)
    fraction = np.ones(len(hits))
    seen = np.all(np.isfinite(hits), axis=1)
    fraction[seen] = lit_fraction(hits[seen], light_samples(spec), cd)
    along = fraction.reshape(len(expected), len(steps))
    return (along.max(axis=1) - along.min(axis=1)) > LIT_CHANGE


def clear_rim(spec, camera: CameraModel, cd: CDGeometry, count: int, search_px: float) -> tuple[np.ndarray, np.ndarray]:
    """The grating's rim projected (pixels (count, 2)) and which of its points a search within
    ``search_px`` can trust: no border of the CD's shadow in reach."""
    expected = camera.project(cd.rim_points(count=count))
    return expected, ~shadow_in_reach(spec, camera, cd, expected, search_px)

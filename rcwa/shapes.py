"""Shapes inside a layer's unit cell: 1D stripes; 2D rectangles, circles and polygons.

Each shape knows its exact Fourier transform (rcwa.fourier), the chords a line cuts
through it (for Li's rule, which works slab by slab) and its outline (for overlap checks
and the normal vector field). Lengths in micrometres, cell coordinates ``[0, L)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import numpy as np
import shapely
import shapely.affinity
from shapely.geometry import Point
from shapely.geometry import Polygon as ShapelyPolygon

from rcwa import fourier
from rcwa.materials import Material

# Circles are drawn as regular polygons with this many sides where an outline is needed
# (overlap tests, visible parts of overlapping shapes, the normal vector field); their
# Fourier transform is exact whenever they overlap nothing.
CIRCLE_OUTLINE_SIDES = 720


@dataclass(frozen=True)
class Stripe:
    """A 1D stripe ``x0 <= x < x1`` (grooves along y)."""

    material: Material
    x0: float
    x1: float


@dataclass(frozen=True)
class Rect:
    material: Material
    center: tuple[float, float]
    size: tuple[float, float]

    def transform(self, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        return fourier.rectangle_transform(self.center, self.size, qx, qy)

    def outline(self) -> ShapelyPolygon:
        (cx, cy), (sx, sy) = self.center, self.size
        return shapely.box(cx - sx / 2, cy - sy / 2, cx + sx / 2, cy + sy / 2)

    def chords(self, coordinate: float, axis: int) -> list[tuple[float, float]]:
        """Intervals along the other axis where the line ``r[axis] = coordinate`` is inside."""
        c, s = self.center, self.size
        if abs(coordinate - c[axis]) < s[axis] / 2:
            other = 1 - axis
            return [(c[other] - s[other] / 2, c[other] + s[other] / 2)]
        return []

    def edges_along(self, axis: int) -> list[float]:
        """Coordinates along ``axis`` where the shape starts or ends (slab boundaries)."""
        return [self.center[axis] - self.size[axis] / 2, self.center[axis] + self.size[axis] / 2]


@dataclass(frozen=True)
class Circle:
    material: Material
    center: tuple[float, float]
    radius: float

    def transform(self, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        return fourier.circle_transform(self.center, self.radius, qx, qy)

    def outline(self) -> ShapelyPolygon:
        return Point(self.center).buffer(self.radius, quad_segs=CIRCLE_OUTLINE_SIDES // 4)

    def chords(self, coordinate: float, axis: int) -> list[tuple[float, float]]:
        offset = coordinate - self.center[axis]
        if abs(offset) >= self.radius:
            return []
        half = np.sqrt(self.radius**2 - offset**2)
        c = self.center[1 - axis]
        return [(c - half, c + half)]

    def edges_along(self, axis: int) -> list[float]:
        return [self.center[axis] - self.radius, self.center[axis] + self.radius]


@dataclass(frozen=True)
class Polygon:
    material: Material
    vertices: tuple[tuple[float, float], ...]

    def transform(self, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        return fourier.polygon_transform(np.asarray(self.vertices), qx, qy)

    def outline(self) -> ShapelyPolygon:
        return ShapelyPolygon(self.vertices)

    def chords(self, coordinate: float, axis: int) -> list[tuple[float, float]]:
        v = np.asarray(self.vertices, dtype=float)
        a, b = v, np.roll(v, -1, axis=0)
        other = 1 - axis
        crossings = []
        for p, q in zip(a, b, strict=True):
            lo, hi = sorted((p[axis], q[axis]))
            if lo <= coordinate < hi:  # half-open: a vertex is counted once
                t = (coordinate - p[axis]) / (q[axis] - p[axis])
                crossings.append(p[other] + t * (q[other] - p[other]))
        crossings.sort()
        return list(zip(crossings[0::2], crossings[1::2], strict=True))  # a closed outline is crossed an even number of times

    def edges_along(self, axis: int) -> list[float]:
        return [float(p[axis]) for p in self.vertices]


Shape2D = Union[Rect, Circle, Polygon]
Shape = Union[Stripe, Rect, Circle, Polygon]


def periodic_copies(geometry, period: tuple[float, float]):
    """The geometry and its 8 neighbours' translates (for overlaps across the cell edge)."""
    lx, ly = period
    return [shapely.affinity.translate(geometry, i * lx, j * ly) for i in (-1, 0, 1) for j in (-1, 0, 1)]


def overlapping_pairs(shapes: list[Shape2D], period: tuple[float, float]) -> list[tuple[int, int]]:
    """Index pairs of shapes whose interiors overlap, periodic images included."""
    outlines = [s.outline() for s in shapes]
    pairs = []
    for i, a in enumerate(outlines):
        for j in range(i + 1, len(outlines)):
            if any(a.intersection(c).area > 1e-12 * a.area for c in periodic_copies(outlines[j], period)):
                pairs.append((i, j))
    return pairs


def visible_regions(shapes: list[Shape2D], period: tuple[float, float]) -> list[list[fourier.Polygon2D]]:
    """For each shape, the polygons of the part no later shape covers (painter's order)."""
    outlines = [s.outline() for s in shapes]
    result: list[list[fourier.Polygon2D]] = []
    for k, outline in enumerate(outlines):
        covering = [c for later in outlines[k + 1 :] for c in periodic_copies(later, period)]
        visible = outline.difference(shapely.union_all(covering)) if covering else outline
        parts = list(getattr(visible, "geoms", [visible]))
        result.append(
            [
                fourier.Polygon2D(
                    exterior=np.asarray(p.exterior.coords)[:-1],
                    holes=tuple(np.asarray(h.coords)[:-1] for h in p.interiors),
                )
                for p in parts
                if isinstance(p, ShapelyPolygon) and not p.is_empty
            ]
        )
    return result

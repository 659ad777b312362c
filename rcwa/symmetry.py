"""Mirror symmetries of a structure's cell, used to shrink the azimuth range of a table
and, for 2D cells, to split a solve into mirror-symmetry sectors (rcwa/cpp/sectors.hpp).

A mirror x -> 2c - x of every layer (the same c for all layers) maps incidence at azimuth
phi to 180 - phi and order m to -m with the same efficiencies; y -> 2c - y maps phi to -phi
and n to -n. A 1D cell is always mirror-symmetric in y. Detection is exact (shapes are
matched geometrically, not sampled, to TOLERANCE_GEOMETRY); cells with overlapping 2D
shapes are reported as not symmetric (conservative: the table then covers the wider
azimuth range, and a solve takes the general path).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcwa import fourier
from rcwa.shapes import Circle, Polygon, Rect, Stripe, overlapping_pairs
from rcwa.structure import Structure

TOLERANCE_GEOMETRY = 1e-9  # micrometres


@dataclass(frozen=True)
class MirrorSymmetry:
    x: bool  # mirror x -> -x (phi -> 180 - phi, m -> -m)
    y: bool  # mirror y -> -y (phi -> -phi, n -> -n)

    def azimuth_range(self) -> tuple[float, float]:
        """The azimuth range (degrees) a table needs; symmetry fills in the rest."""
        if self.x and self.y:
            return 0.0, 90.0
        if self.y:
            return 0.0, 180.0
        if self.x:
            return -90.0, 90.0
        return 0.0, 360.0

    def describe(self) -> str:
        names = [n for n, v in (("x -> -x", self.x), ("y -> -y", self.y)) if v]
        return "mirror " + " and ".join(names) if names else "none"


def detect(structure: Structure) -> MirrorSymmetry:
    if structure.dimension == 1:
        return MirrorSymmetry(x=_lamellar_mirror(structure), y=True)
    return MirrorSymmetry(x=_crossed_mirror(structure, axis=0) is not None,
                          y=_crossed_mirror(structure, axis=1) is not None)


def mirror_centres(structure: Structure) -> tuple[float | None, float | None]:
    """The lines x = c (first) and y = c (second) a 2D cell is mirror-symmetric about,
    in micrometres of the cell's coordinates (None: no such mirror)."""
    if structure.dimension != 2:
        raise ValueError("mirror_centres: expected a 2D structure")
    return _crossed_mirror(structure, axis=0), _crossed_mirror(structure, axis=1)


CoreMirror = tuple[int, list[int], list[complex]]


def core_mirrors(structure: Structure, m: np.ndarray, n: np.ndarray, dkx: np.ndarray, dky: np.ndarray,
                 k0: float) -> list[CoreMirror]:
    """A 2D cell's mirrors as the core takes them (rcwa/cpp/sweep.hpp, Mirror): (axis,
    partner, phase) with harmonic (m, n)'s image (-m, n) (axis 0) or (m, -n) (axis 1), and
    phase exp(2 i k0 kx c) (resp. ky), the factor a scalar field's harmonic picks up under
    x -> 2c - x at kx0 = 0 (rcwa/cpp/sectors.hpp). ``dkx``, ``dky``: the harmonics' offsets
    / k0; ``k0`` in 1/um. Mirrors whose image of a retained harmonic is not retained
    (never, for the solver's symmetric truncation) are left out."""
    index = {(int(a), int(b)): i for i, (a, b) in enumerate(zip(m.tolist(), n.tolist(), strict=True))}
    out: list[CoreMirror] = []
    for axis, (centre, offsets) in enumerate(zip(mirror_centres(structure), (dkx, dky), strict=True)):
        if centre is None:
            continue
        images = [((-a, b) if axis == 0 else (a, -b)) for a, b in index]
        if any(key not in index for key in images):
            continue
        partner = [index[key] for key in images]
        phase = np.exp(2j * k0 * np.asarray(offsets, dtype=float) * centre)
        out.append((axis, partner, phase.tolist()))
    return out


def _lamellar_mirror(structure: Structure) -> bool:
    period = structure.period[0]
    profiles = []
    for layer in structure.layers:
        stripes = [(s.x0, s.x1, s.material) for s in layer.shapes if isinstance(s, Stripe)]
        profiles.append(fourier.paint_intervals(period, layer.material, stripes))
    patterned = [p for p in profiles if len(p) > 1]
    if not patterned:
        return True
    candidates = set()
    for a, b, _ in patterned[0]:
        for c in (a, 0.5 * (a + b)):
            candidates.update({round(c % period, 12), round((c + period / 2) % period, 12)})
    return any(all(_profile_mirrors(p, period, c) for p in patterned) for c in candidates)


def _value_at(segments, x: float):
    for a, b, v in segments:
        if a <= x < b:
            return v
    return segments[-1][2]


def _profile_mirrors(segments, period: float, c: float) -> bool:
    for a, b, v in segments:
        probe = 0.5 * (a + b)
        if _value_at(segments, (2 * c - probe) % period) != v:
            return False
    edges = sorted(a for a, _, _ in segments)
    mirrored = sorted((2 * c - e) % period for e in edges)
    return all(
        min(abs(e - m), period - abs(e - m)) < TOLERANCE_GEOMETRY for e, m in zip(sorted(edges), mirrored, strict=True)
    )


def _crossed_mirror(structure: Structure, axis: int) -> float | None:
    """A centre c the cell is mirror-symmetric about along ``axis`` (x -> 2c - x), or None."""
    lx, ly = structure.period
    length = (lx, ly)[axis]
    layers = [layer for layer in structure.layers if layer.shapes]
    if not layers:
        return 0.0
    if any(overlapping_pairs(list(layer.shapes_2d), (lx, ly)) for layer in layers):
        return None
    first = layers[0].shapes_2d[0]
    # Candidates, deduplicated by their rounded value but kept exact: the sectors' phases
    # (core_mirrors) use the centre itself.
    centres = (((_center(first)[axis] + _center(s)[axis]) / 2) % (length / 2) for s in layers[0].shapes_2d)
    candidates = {round(c, 12): c for c in centres}.values()
    for c in candidates:
        for shift in (0.0, length / 2):
            if all(_layer_mirrors(layer.shapes_2d, c + shift, axis, structure.period) for layer in layers):
                return float(c + shift)
    return None


def _center(shape) -> tuple[float, float]:
    if isinstance(shape, (Rect, Circle)):
        return shape.center
    v = np.asarray(shape.vertices)
    return float(v[:, 0].mean()), float(v[:, 1].mean())


def _reflect(shape, c: float, axis: int):
    def point(p):
        q = list(p)
        q[axis] = 2 * c - q[axis]
        return tuple(q)

    if isinstance(shape, Rect):
        return Rect(shape.material, point(shape.center), shape.size)
    if isinstance(shape, Circle):
        return Circle(shape.material, point(shape.center), shape.radius)
    return Polygon(shape.material, tuple(point(v) for v in shape.vertices))


def _periodic_gap(p: float, q: float, length: float) -> float:
    """The distance between ``p`` and ``q`` on a circle of circumference ``length``."""
    gap = abs(p - q) % length
    return min(gap, length - gap)


def _same_shape(a, b, period) -> bool:
    if type(a) is not type(b) or a.material != b.material:
        return False

    def close(p, q):
        return all(_periodic_gap(pi, qi, L) < TOLERANCE_GEOMETRY for pi, qi, L in zip(p, q, period, strict=True))

    if isinstance(a, Rect):
        return close(a.center, b.center) and np.allclose(a.size, b.size, atol=TOLERANCE_GEOMETRY)
    if isinstance(a, Circle):
        return close(a.center, b.center) and abs(a.radius - b.radius) < TOLERANCE_GEOMETRY
    if len(a.vertices) != len(b.vertices):
        return False
    return all(any(close(p, q) for q in b.vertices) for p in a.vertices)


def _layer_mirrors(shapes, c: float, axis: int, period) -> bool:
    return all(any(_same_shape(_reflect(s, c, axis), t, period) for t in shapes) for s in shapes)

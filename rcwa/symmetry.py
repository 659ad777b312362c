"""Mirror symmetries of a structure's cell, used to shrink the azimuth range of a table
and, for 2D cells, to split a solve into mirror-symmetry sectors (rcwa/cpp/sectors.hpp).

A mirror x -> 2c - x of every layer (the same c for all layers) maps incidence at azimuth
phi to 180 - phi and order m to -m with the same efficiencies; y -> 2c - y maps phi to -phi
and n to -n. A 1D cell is always mirror-symmetric in y. A 2D cell with both mirrors, a
square period and the diagonal mirror x <-> y (about a line of slope 1 through a crossing
of the x and y mirror lines) maps phi to 90 - phi and order (m, n) to (n, m); the
truncation must then be square too (the same order count along x and y) for the swap to
be a symmetry of the truncated problem. Efficiencies do not depend on where the cell's
origin is, so only the mirrors' existence matters for the fold (fold_azimuths), not their
position. Detection is exact (shapes are matched geometrically, not sampled, to
TOLERANCE_GEOMETRY); cells with overlapping 2D shapes are reported as not symmetric
(conservative: the table then covers the wider azimuth range, and a solve takes the
general path).
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
    diagonal: bool = False  # mirror x <-> y, used only with x and y (phi -> 90 - phi, (m, n) -> (n, m))
    note: str = ""  # why a mirror the cell has is not used (a truncation that breaks it)

    def __post_init__(self) -> None:
        if self.diagonal and not (self.x and self.y):
            raise ValueError("MirrorSymmetry: the diagonal mirror is used only together with the x and y mirrors")

    def azimuth_range(self) -> tuple[float, float]:
        """The azimuth range (degrees) a table needs; symmetry fills in the rest."""
        if self.diagonal:
            return 0.0, 45.0
        if self.x and self.y:
            return 0.0, 90.0
        if self.y:
            return 0.0, 180.0
        if self.x:
            return -90.0, 90.0
        return 0.0, 360.0

    def describe(self) -> str:
        names = [n for n, v in (("x -> -x", self.x), ("y -> -y", self.y), ("diagonal x <-> y", self.diagonal)) if v]
        text = "mirror " + " and ".join(names) if names else "none"
        return f"{text} ({self.note})" if self.note else text


def detect(structure: Structure, orders: int | tuple[int, ...] | None = None,
           keep: int | tuple[int, ...] | None = None) -> MirrorSymmetry:
    """The cell's mirrors a table may use. ``orders`` / ``keep``: the retained and kept
    order counts (per direction); the diagonal mirror is used only where both are square
    (None: not checked), otherwise ``note`` says why it is not."""
    if structure.dimension == 1:
        return MirrorSymmetry(x=_lamellar_mirror(structure), y=True)
    cx, cy = mirror_centres(structure)
    x, y = cx is not None, cy is not None
    if cx is None or cy is None or not _diagonal_mirror(structure, cx, cy):
        return MirrorSymmetry(x, y)
    unsquare = [f"{name} {'x'.join(map(str, c))}" for name, c in (("orders", _pair(orders)), ("kept orders", _pair(keep)))
                if c is not None and c[0] != c[1]]
    if unsquare:
        return MirrorSymmetry(x, y, note=f"the cell's diagonal mirror x <-> y is not used: {', '.join(unsquare)} not square")
    return MirrorSymmetry(x, y, diagonal=True)


def has_diagonal_mirror(structure: Structure) -> bool:
    """Whether a 2D cell has the x and y mirrors, a square period and the diagonal mirror
    x <-> y (geometry only; a table also needs a square truncation: detect)."""
    if structure.dimension != 2:
        return False
    cx, cy = mirror_centres(structure)
    return cx is not None and cy is not None and _diagonal_mirror(structure, cx, cy)


def _pair(counts: int | tuple[int, ...] | None) -> tuple[int, int] | None:
    if counts is None:
        return None
    values = (counts, counts) if isinstance(counts, (int, np.integer)) else tuple(counts)
    return (int(values[0]), int(values[-1]))


def fold_azimuths(phi_deg, mirror_x: bool, mirror_y: bool,
                  diagonal: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Azimuths (degrees, any) mapped into a table's stored range (MirrorSymmetry.azimuth_range),
    with what the order undergoes: ``(phi, flip_m, flip_n, swap)``.

    The efficiency of order (m, n) at the given azimuth is the stored one at the folded
    azimuth of order ``stored_order(m, n, flip_m, flip_n, swap)``: the flips first, then the
    swap. The folds are applied in this order: y (phi > 180 -> 360 - phi, n -> -n), then x
    (phi > 90 -> 180 - phi, m -> -m; without the y mirror: 90 < phi < 270, and phi >= 270
    -> phi - 360), then the diagonal (phi > 45 -> 90 - phi, (m, n) -> (n, m)). Every reader
    of a table uses this rule (the renderer's Dr.Jit copy, renderer.efficiency, is tested
    against it). Boundaries map to themselves (90 stays 90 without a flip, 45 stays 45)."""
    phi = np.mod(np.asarray(phi_deg, dtype=float), 360.0)
    flip_m = np.zeros(phi.shape, bool)
    flip_n = np.zeros(phi.shape, bool)
    swap = np.zeros(phi.shape, bool)
    if diagonal and not (mirror_x and mirror_y):
        raise ValueError("fold_azimuths: the diagonal mirror is used only together with the x and y mirrors")
    if mirror_y:
        flip_n = phi > 180.0
        phi = np.where(flip_n, 360.0 - phi, phi)
        if mirror_x:
            flip_m = phi > 90.0
            phi = np.where(flip_m, 180.0 - phi, phi)
        if diagonal:
            swap = phi > 45.0
            phi = np.where(swap, 90.0 - phi, phi)
    elif mirror_x:
        flip_m = (phi > 90.0) & (phi < 270.0)
        phi = np.where(flip_m, 180.0 - phi, np.where(phi >= 270.0, phi - 360.0, phi))
    return phi, flip_m, flip_n, swap


def stored_order(m, n, flip_m, flip_n, swap) -> tuple[np.ndarray, np.ndarray]:
    """The stored order that holds order (m, n) after fold_azimuths (flips, then the swap)."""
    m2 = np.where(flip_m, -np.asarray(m), m)
    n2 = np.where(flip_n, -np.asarray(n), n)
    return np.where(swap, n2, m2), np.where(swap, m2, n2)


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

    if isinstance(a, Rect):  # absolute tolerance only: numpy's default rtol would pass sizes 1e-5 apart
        return close(a.center, b.center) and np.allclose(a.size, b.size, rtol=0.0, atol=TOLERANCE_GEOMETRY)
    if isinstance(a, Circle):
        return close(a.center, b.center) and abs(a.radius - b.radius) < TOLERANCE_GEOMETRY
    if len(a.vertices) != len(b.vertices):
        return False
    return all(any(close(p, q) for q in b.vertices) for p in a.vertices)


def _layer_mirrors(shapes, c: float, axis: int, period) -> bool:
    return all(any(_same_shape(_reflect(s, c, axis), t, period) for t in shapes) for s in shapes)


def _diagonal_mirror(structure: Structure, cx: float, cy: float) -> bool:
    """Whether the cell (with mirrors x = cx and y = cy) is also symmetric about a line of
    slope 1 through a crossing of its mirror lines: (cx, cy) or (cx + L/2, cy), the mirror
    lines repeating every half period (the lines through (cx, cy + L/2) and (cx + L/2,
    cy + L/2) are those two again). Needs a square period."""
    lx, ly = structure.period
    if abs(lx - ly) >= TOLERANCE_GEOMETRY:
        return False
    layers = [layer for layer in structure.layers if layer.shapes]
    return any(all(_layer_mirrors_diagonally(layer.shapes_2d, ox, cy, structure.period) for layer in layers)
               for ox in (cx, cx + lx / 2))


def _reflect_diagonal(shape, cx: float, cy: float):
    """``shape`` mirrored about the line y - cy = x - cx: (x, y) -> (cx + y - cy, cy + x - cx)."""
    def point(p):
        return (cx + p[1] - cy, cy + p[0] - cx)

    if isinstance(shape, Rect):
        return Rect(shape.material, point(shape.center), (shape.size[1], shape.size[0]))
    if isinstance(shape, Circle):
        return Circle(shape.material, point(shape.center), shape.radius)
    return Polygon(shape.material, tuple(point(v) for v in shape.vertices))


def _layer_mirrors_diagonally(shapes, cx: float, cy: float, period) -> bool:
    return all(any(_same_shape(_reflect_diagonal(s, cx, cy), t, period) for t in shapes) for s in shapes)

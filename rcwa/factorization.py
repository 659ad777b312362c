"""Fourier factorization rules: the permittivity matrices a layer's eigenproblem uses.

Each rule returns :class:`PermittivityMatrices` for one layer at one wavelength; the
solver's PQ eigenproblem (rcwa/cpp/modes.hpp) takes the Laurent matrix ``E = [[eps]]``
(for ``E_z``: ``Z = E^{-1}``) and the in-plane tensor ``[Exx Exy; Eyx Eyy]``. The rules,
one function each (``laurent_rule``, ``li_rule``, ``nv_rule``, ``auto_rule``), all with the
signature ``FactorizationRule``, are chosen by name in ``FACTORIZATION_RULES``:

* ``laurent``: ``Exx = Eyy = [[eps]]`` (the classical, slowly converging choice; kept so
  the difference can be measured).
* ``li``: 1D: Li's inverse rule ``Exx = [[1/eps]]^{-1}``, ``Eyy = [[eps]]``
  ([Li 1996, Theorems 1-2 and Eq. 37]; [Lalanne 1996], [Granet 1996]).
  2D: [Li 1997, Eqs. 38-39]: ``Exx`` applies the inverse rule along x
  inside each y-slab and the Laurent rule along y; ``Eyy`` the reverse. Exact for shapes
  that are unions of axis-aligned rectangles; circles and polygons are cut into
  ``LI_STAIRCASE_SLABS`` slabs (a staircase) along the Laurent direction.
* ``nv``: the normal vector method ([Schuster 2007, Eqs. 15-18]; [Götz 2008]): with a unit field n(r)
  normal to every material boundary, ``Exx = E - Delta [[nx nx]]``, ``Exy = -Delta
  [[nx ny]]``, ``Eyy = E - Delta [[ny ny]]``, ``Delta = [[eps]] - [[1/eps]]^{-1}``. In 1D
  n = x everywhere and it is the same as ``li``.
* ``auto``: ``li`` in 1D and for 2D cells made only of rectangles (where [Li 1997] is the
  correct rule in both directions), ``nv`` for 2D cells with circles or polygons.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Callable

import numpy as np
import shapely
from shapely import affinity

from rcwa import _core, fourier
from rcwa.shapes import Circle, Rect, Stripe, overlapping_pairs, visible_regions
from rcwa.structure import Layer
from workbench.core.errors import UserInputError

LI_STAIRCASE_SLABS = 128
NV_GRID = 256  # samples per period for the FFT of the normal-vector field

@dataclass(frozen=True)
class PermittivityMatrices:
    """``E`` is ``[[eps]]``; ``exy``/``eyx`` are None when zero."""

    E: np.ndarray
    exx: np.ndarray
    eyy: np.ndarray
    exy: np.ndarray | None = None
    eyx: np.ndarray | None = None


@dataclass(frozen=True)
class HarmonicIndices:
    """Retained harmonics: ``m`` (and ``n`` in 2D) of each, in solver order."""

    m: np.ndarray
    n: np.ndarray


# A rule: (layer, period (um, one entry per periodic direction), eps_of(material) -> permittivity,
# retained harmonics) -> the layer's matrices at one wavelength.
FactorizationRule = Callable[[Layer, tuple[float, ...], Callable, HarmonicIndices], PermittivityMatrices]


def laurent_rule(layer: Layer, period: tuple[float, ...], eps_of: Callable, h: HarmonicIndices) -> PermittivityMatrices:
    """Laurent's rule: ``Exx = Eyy = [[eps]]`` in 1D and 2D (the classical, slowly
    converging choice, kept so the difference can be measured)."""
    if len(period) == 1:
        E, _ = lamellar_toeplitz(layer, period[0], eps_of, h.m, inverse=False)
        return PermittivityMatrices(E, E, E)
    E = _laurent_matrix(layer, (period[0], period[1]), eps_of, h)
    return PermittivityMatrices(E, E, E)


def li_rule(layer: Layer, period: tuple[float, ...], eps_of: Callable, h: HarmonicIndices) -> PermittivityMatrices:
    """Li's inverse rule. 1D: ``Exx = [[1/eps]]^{-1}``, ``Eyy = [[eps]]`` ([Li 1996,
    Theorems 1-2 and Eq. 37]). 2D: [Li 1997, Eqs. 38-39], ``Exx``
    the inverse rule along x inside each y-slab and the Laurent rule along y, ``Eyy`` the
    reverse (_li_slabbed)."""
    if len(period) == 1:
        return _inverse_rule_1d(layer, period[0], eps_of, h.m)
    E = _laurent_matrix(layer, (period[0], period[1]), eps_of, h)
    exx = _li_slabbed(layer, period, eps_of, h, axis=0)
    return PermittivityMatrices(E, exx, _li_slabbed(layer, period, eps_of, h, axis=1))


def nv_rule(layer: Layer, period: tuple[float, ...], eps_of: Callable, h: HarmonicIndices) -> PermittivityMatrices:
    """The normal vector method ([Schuster 2007, Eqs. 15-18]; [Götz 2008]): ``Exx = E - Delta [[nx
    nx]]``, ``Exy = Eyx = -Delta [[nx ny]]``, ``Eyy = E - Delta [[ny ny]]``, ``Delta = [[eps]]
    - [[1/eps]]^{-1}``, the products symmetrized. In 1D n = x everywhere: Li's inverse rule."""
    if len(period) == 1:
        return _inverse_rule_1d(layer, period[0], eps_of, h.m)
    cell = (period[0], period[1])
    mx, my = _max_orders(h)
    E, delta = nv_delta(layer, cell, eps_of, h)
    nxx, nxy, nyy = (_convolution(c, 2 * mx, 2 * my, h) for c in _normal_products(layer, cell, 2 * mx, 2 * my))
    dxx, dxy, dyy = nv_corrections(delta, nxx, nxy, nyy)
    return PermittivityMatrices(E, E - dxx, E - dyy, -dxy, -dxy)


def nv_delta(layer: Layer, cell: tuple[float, float], eps_of: Callable, h: HarmonicIndices) -> tuple[np.ndarray, np.ndarray]:
    """``[[eps]]`` and the normal-vector method's ``Delta = [[eps]] - [[1/eps]]^{-1}`` [Schuster 2007, Eq. 17]."""
    E = _laurent_matrix(layer, cell, eps_of, h)
    mx, my = _max_orders(h)
    gx, gy = _coefficient_orders(mx, my)
    c_inv = cell_coefficients(layer, cell, lambda mat: 1.0 / eps_of(mat), gx, gy)
    return E, E - np.linalg.inv(_convolution(c_inv, 2 * mx, 2 * my, h))


def nv_corrections(delta: np.ndarray, nxx: np.ndarray, nxy: np.ndarray, nyy: np.ndarray) -> tuple[np.ndarray, ...]:
    """``Delta [[n_i n_j]]`` for xx, xy, yy, each product symmetrized, ``(Delta N + N Delta) / 2``:
    Hermitian for lossless cells, so the truncated problem conserves energy exactly (Delta
    [[N]] alone does not; see docs/architecture.md)."""
    return tuple(0.5 * (delta @ N + N @ delta) for N in (nxx, nxy, nyy))


def auto_rule(layer: Layer, period: tuple[float, ...], eps_of: Callable, h: HarmonicIndices) -> PermittivityMatrices:
    """``li`` in 1D and for 2D cells made only of rectangles (where [Li 1997] is the correct
    rule in both directions), ``nv`` for 2D cells with circles or polygons (resolve_rule)."""
    return FACTORIZATION_RULES[resolve_rule("auto", len(period), (layer,))](layer, period, eps_of, h)


# The rules by the names the command line, scene files and tables use (in the order the
# command line's help lists them).
FACTORIZATION_RULES: dict[str, FactorizationRule] = {
    "auto": auto_rule, "li": li_rule, "nv": nv_rule, "laurent": laurent_rule,
}


def resolve_rule(rule: str, dimension: int, layers: tuple[Layer, ...] = ()) -> str:
    """The rule ``rule`` names (``auto`` resolved for these layers); UserInputError for an unknown name."""
    if rule not in FACTORIZATION_RULES:
        raise UserInputError(
            "unknown factorization rule", field="factorization", expected=f"one of {tuple(sorted(FACTORIZATION_RULES))}",
            got=rule,
        )
    if rule == "auto":
        only_rectangles = all(isinstance(s, (Rect, Stripe)) for layer in layers for s in layer.shapes)
        return "li" if dimension == 1 or only_rectangles else "nv"
    return rule


def permittivity_matrices(
    layer: Layer,
    period: tuple[float, ...],
    eps_of: Callable,
    harmonics: HarmonicIndices,
    rule: str,
) -> PermittivityMatrices:
    """The matrices of a patterned layer by the rule named ``rule`` (FACTORIZATION_RULES);
    ``eps_of(material)`` gives its permittivity."""
    return FACTORIZATION_RULES[resolve_rule(rule, len(period), (layer,))](layer, period, eps_of, harmonics)


# ---------------------------------------------------------------- 1D


def _inverse_rule_1d(layer: Layer, period: float, eps_of: Callable, m: np.ndarray) -> PermittivityMatrices:
    """The inverse rule [Li 1996, Eq. 37] of a 1D layer: ``Exx = [[1/eps]]^{-1}``, ``Eyy = [[eps]]``."""
    E, inverse = lamellar_toeplitz(layer, period, eps_of, m, inverse=True)
    assert inverse is not None  # asked for: inverse=True
    return PermittivityMatrices(E, np.linalg.inv(inverse), E)


def lamellar_toeplitz(layer: Layer, period: float, eps_of: Callable, m: np.ndarray,
                      inverse: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """``[[eps]]`` and, with ``inverse``, ``[[1/eps]]`` of a 1D layer for harmonics ``m = -M..M``
    ([Li 1996, Eq. 3] for the Toeplitz matrices; Li's inverse rule is ``Exx =
    [[1/eps]]^-1``, which the solver leaves to the core: rcwa/cpp/sweep.hpp,
    ``LayerInput::inverse_rule``). Built by the core from the profile (rcwa/cpp/profile.hpp,
    the closed-form interval transforms of rcwa.fourier); without ``inverse`` the second
    matrix is None."""
    core = _core.LayerInput.lamellar(0.0, period, lamellar_profile(layer, period, eps_of), int(m.size), inverse)
    E, second = core.matrices
    return E, (second if inverse else None)


def lamellar_profile(layer: Layer, period: float, eps_of: Callable) -> list[tuple[float, float, complex]]:
    """A 1D layer's permittivity as ``(x0, x1, eps)`` segments covering ``[0, period)``
    (rcwa.fourier.paint_intervals: later stripes over earlier ones, wrapped into the cell)."""
    stripes = [s for s in layer.shapes if isinstance(s, Stripe)]
    eps_bg = complex(eps_of(layer.material))
    return fourier.paint_intervals(period, eps_bg, [(s.x0, s.x1, complex(eps_of(s.material))) for s in stripes])


def _toeplitz_centred(c: np.ndarray, m: np.ndarray) -> np.ndarray:
    """The convolution matrix of coefficients ``c`` listed for ``g = -G..G`` (``g = 0`` at the centre)."""
    return fourier.toeplitz(lambda d: c[d + c.size // 2], m)


# ---------------------------------------------------------------- 2D


def cell_coefficients(
    layer: Layer, period: tuple[float, float], value_of: Callable, gx: np.ndarray, gy: np.ndarray
) -> np.ndarray:
    """Exact Fourier coefficients ``c(gx, gy)`` of ``value_of(material)`` over the cell.

    Shapes that overlap nothing add ``(v_shape - v_background) * FT(shape) / area``;
    overlapping shapes are first cut into their visible polygons (painter's order).
    """
    lx, ly = period
    qx = 2 * np.pi * gx[:, None] / lx + 0 * gy[None, :]
    qy = 2 * np.pi * gy[None, :] / ly + 0 * gx[:, None]
    area = lx * ly
    v_bg = complex(value_of(layer.material))
    c = np.where((qx == 0) & (qy == 0), v_bg, 0.0).astype(complex)
    shapes = list(layer.shapes_2d)
    if len(shapes) < 2 or not overlapping_pairs(shapes, period):  # one shape overlaps nothing (no shapely outline)
        for s in shapes:
            c += (complex(value_of(s.material)) - v_bg) * s.transform(qx, qy) / area
        return c
    for s, regions in zip(shapes, visible_regions(shapes, period), strict=True):
        for region in regions:
            c += (complex(value_of(s.material)) - v_bg) * fourier.region_transform(region, qx, qy) / area
    return c


def _convolution(c: np.ndarray, gx0: int, gy0: int, h: HarmonicIndices) -> np.ndarray:
    """``C[i, j] = c[m_j - m_i + gx0, n_j - n_i + gy0]``, gathered through one flat index
    (the row-major position of (m, n) in ``c`` is linear in both): a tenth of the time of the
    two-array fancy index at 15 x 15 orders, the same values."""
    width = c.shape[1]
    flat = h.m * width + h.n
    return c.ravel().take(flat[None, :] - flat[:, None] + (gx0 * width + gy0))


def _max_orders(h: HarmonicIndices) -> tuple[int, int]:
    return int(np.max(np.abs(h.m))), int(np.max(np.abs(h.n)))


def _coefficient_orders(mx: int, my: int) -> tuple[np.ndarray, np.ndarray]:
    """The Fourier orders (gx, gy) a convolution matrix of harmonics up to (mx, my) reads."""
    return np.arange(-2 * mx, 2 * mx + 1), np.arange(-2 * my, 2 * my + 1)


def _laurent_matrix(layer: Layer, period: tuple[float, float], eps_of: Callable, h: HarmonicIndices) -> np.ndarray:
    """``E = [[eps]]`` of a 2D layer (Laurent's rule)."""
    mx, my = _max_orders(h)
    gx, gy = _coefficient_orders(mx, my)
    return _convolution(cell_coefficients(layer, period, eps_of, gx, gy), 2 * mx, 2 * my, h)


def _slab_edges(layer: Layer, length: float, axis: int) -> np.ndarray:
    """Boundaries of slabs along ``axis`` inside which every cut is the same (or a staircase)."""
    edges = {0.0, length}
    for s in layer.shapes_2d:
        edges.update(float(e) % length for e in s.edges_along(axis))
    if any(not isinstance(s, Rect) for s in layer.shapes_2d):
        edges.update(np.linspace(0.0, length, LI_STAIRCASE_SLABS + 1).tolist())
    return np.array(sorted(edges))


def _li_slabbed(layer: Layer, period, eps_of: Callable, h: HarmonicIndices, axis: int) -> np.ndarray:
    """[Li 1997, Eqs. 38-39]: inverse rule along ``axis`` inside each slab, Laurent across the slabs.

    axis = 0 gives Exx (slabs stacked along y, inverse rule along x); axis = 1 gives Eyy.
    """
    along, across = period[axis], period[1 - axis]
    idx_along = h.m if axis == 0 else h.n
    idx_across = h.n if axis == 0 else h.m
    m_along = np.arange(-int(np.max(np.abs(idx_along))), int(np.max(np.abs(idx_along))) + 1)
    ga = np.arange(-2 * m_along[-1], 2 * m_along[-1] + 1)
    g_across = np.arange(-2 * int(np.max(np.abs(idx_across))), 2 * int(np.max(np.abs(idx_across))) + 1)
    edges = _slab_edges(layer, across, 1 - axis)
    eps_bg = complex(eps_of(layer.material))
    slabs = []  # (a, b, the cut's segments along) of every slab
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        if b - a <= 1e-15:
            continue
        cut = 0.5 * (a + b)
        intervals = []
        for s in layer.shapes_2d:
            for shift in (-across, 0.0, across):
                for x0, x1 in s.chords(cut + shift, 1 - axis):
                    intervals.append((x0, x1, 1.0 / complex(eps_of(s.material))))
        slabs.append((a, b, tuple(fourier.paint_intervals(along, 1.0 / eps_bg, _clip_intervals(intervals, along)))))
    # Slabs with the same cut (the background's on both sides of a block) share one inverse.
    cuts = list(dict.fromkeys(segments for _, _, segments in slabs))
    pieces = [piece for segments in cuts for piece in segments]
    along_t = _interval_transforms(2.0 * np.pi * np.asarray(ga, dtype=float) / along, pieces)
    across_t = _interval_transforms(2 * np.pi * g_across / across, slabs)
    inverses: dict[tuple, np.ndarray] = {}
    row = 0
    for segments in cuts:
        # fourier.profile_coefficients, its sum in the same order
        coefficients = np.zeros(ga.shape, dtype=complex)
        for (_, _, value), transform in zip(segments, along_t[row:row + len(segments)], strict=True):
            coefficients += value * transform
        row += len(segments)
        inverses[segments] = np.linalg.inv(_toeplitz_centred(coefficients / along, m_along))
    # total[i, j, g]: coefficient g (across) of the slab-wise inverse-rule matrix entry (i, j).
    total = np.zeros((m_along.size, m_along.size, g_across.size), dtype=complex)
    for (_, _, segments), transform in zip(slabs, across_t, strict=True):
        total += inverses[segments][:, :, None] * transform[None, None, :] / across
    # total[i_r, i_c, n_c - n_r + G // 2] (i: index along, n: order across, G: g_across.size),
    # through one flat index (row-major: (i_r M + i_c) G + d), split into its row's and its
    # column's parts: the same values as the three-array fancy index, several times faster.
    i, size_g = idx_along - m_along[0], g_across.size
    rows = i * (m_along.size * size_g) - idx_across
    cols = i * size_g + idx_across + size_g // 2
    return total.ravel().take(rows[:, None] + cols[None, :])


def _interval_transforms(q: np.ndarray, intervals) -> np.ndarray:
    """fourier.interval_transform of every ``(a, b, ...)`` in ``intervals`` at once (one row each)."""
    a = np.array([iv[0] for iv in intervals], dtype=float)[:, None]
    b = np.array([iv[1] for iv in intervals], dtype=float)[:, None]
    return fourier.interval_transform(q, a, b)


def _clip_intervals(intervals, length: float):
    """Drop empty chords and split chords longer than the period (images overlapping)."""
    out = []
    for x0, x1, v in intervals:
        if x1 - x0 <= 0:
            continue
        out.append((x0, min(x1, x0 + length), v))
    return out


@lru_cache(maxsize=64)
def _normal_products(layer: Layer, period: tuple[float, float], gx_max: int, gy_max: int):
    """Fourier coefficients of nx^2, nx ny, ny^2 of the normal-vector field.

    n(r) is the gradient of the distance to the nearest material boundary, i.e. the unit
    vector from the nearest boundary point to r ([Götz 2008, Sec. 3]): normal to
    every boundary, radial around corners, continuous except on the medial axis, where
    the tensor n n^T of equally near boundary points is averaged (so a symmetric cell
    gets a symmetric field). Sampled at the centres of an NV_GRID x NV_GRID grid and
    transformed by FFT. The field depends on the geometry only, not on the wavelength or
    the angles, so it is cached per layer (a sweep computes it once).
    """
    lx, ly = period
    centres = (np.arange(NV_GRID) + 0.5) / NV_GRID
    return normal_products_at(layer, period, centres * lx, centres * ly, gx_max, gy_max)


def normal_products_at(layer: Layer, period: tuple[float, float], xs: np.ndarray, ys: np.ndarray, gx_max: int,
                       gy_max: int) -> list[np.ndarray]:
    """_normal_products' coefficients over the cell's uniform sample grid, the field taken at the
    points (xs[i], ys[j]) that grid's i-th column and j-th row stand for: the identity for the
    uniform grid, or the image of a stretched coordinate's grid (rcwa.asr)."""
    gx, gy = np.arange(-gx_max, gx_max + 1), np.arange(-gy_max, gy_max + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    fields = _normal_tensor(layer, period, np.stack([X.ravel(), Y.ravel()], axis=1))
    phase = np.exp(-1j * np.pi * (gx[:, None] / xs.size + gy[None, :] / ys.size))
    out = []
    for f in fields:
        spectrum = np.fft.fft2(f.reshape(xs.size, ys.size)) / f.size
        out.append(spectrum[np.ix_(gx % xs.size, gy % ys.size)] * phase)
    return out


def _boundary_candidates(layer: Layer, period, points: np.ndarray):
    """Distance to, and unit normal from, each boundary piece (edges, circles, images).

    A polygon's boundary is taken from the union of its periodic images, so an edge that
    meets its own image (a rectangle spanning the whole period in y has its top edge on
    its image's bottom edge) is no material boundary and does not pull the normal field:
    in a y-invariant cell every boundary is then normal to x, and [Schuster 2007]'s
    rule reduces to Li's 1D inverse rule (tests/rcwa/test_invariance.py). Coordinates are
    snapped to 1e-9 of the period first, so images that should touch do touch exactly.
    """
    lx, ly = period
    dists, normals_x, normals_y = [], [], []
    for s in layer.shapes_2d:
        if isinstance(s, Circle):
            for dx in (-lx, 0.0, lx):
                for dy in (-ly, 0.0, ly):
                    rel = points - (np.array(s.center) + [dx, dy])
                    r = np.hypot(rel[:, 0], rel[:, 1])
                    safe = np.where(r == 0, 1.0, r)
                    dists.append(np.abs(r - s.radius)[:, None])
                    normals_x.append((rel[:, 0] / safe)[:, None])
                    normals_y.append((rel[:, 1] / safe)[:, None])
            continue
        start, step = _periodic_boundary_segments(s.outline(), period, points)
        if not len(start):
            continue
        length2 = np.sum(step * step, axis=1)
        t = np.clip(((points[:, None, :] - start[None]) * step[None]).sum(-1) / length2[None], 0.0, 1.0)
        rel = points[:, None, :] - (start[None] + t[..., None] * step[None])
        dist = np.hypot(rel[..., 0], rel[..., 1])
        edge_n = np.stack([step[:, 1], -step[:, 0]], axis=1) / np.sqrt(length2)[:, None]
        on_edge = dist < 1e-12
        safe = np.where(on_edge, 1.0, dist)
        dists.append(dist)
        normals_x.append(np.where(on_edge, edge_n[None, :, 0], rel[..., 0] / safe))
        normals_y.append(np.where(on_edge, edge_n[None, :, 1], rel[..., 1] / safe))
    return np.concatenate(dists, axis=1), np.concatenate(normals_x, axis=1), np.concatenate(normals_y, axis=1)


def _periodic_boundary_segments(outline, period, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segments (start points, steps) of the boundary of the union of a polygon's periodic
    images, within one period of the sample points (the union's outer rim, an artefact of
    tiling only 5 x 5 images, lies further out and is cut away)."""
    lx, ly = period
    grid = 1e-9 * max(lx, ly)
    images = [affinity.translate(outline, i * lx, j * ly) for i in range(-2, 3) for j in range(-2, 3)]
    union = shapely.unary_union([shapely.set_precision(g, grid) for g in images])
    (x0, y0), (x1, y1) = points.min(axis=0), points.max(axis=0)
    near = union.boundary.intersection(shapely.box(x0 - lx, y0 - ly, x1 + lx, y1 + ly))
    lines = getattr(near, "geoms", [near])
    starts, steps = [], []
    for line in lines:
        if line.is_empty or line.geom_type != "LineString":
            continue
        c = np.asarray(line.coords)
        starts.append(c[:-1])
        steps.append(np.diff(c, axis=0))
    if not starts:
        return np.zeros((0, 2)), np.zeros((0, 2))
    start, step = np.concatenate(starts), np.concatenate(steps)
    keep = np.sum(step * step, axis=1) > 0
    return start[keep], step[keep]


def _normal_tensor(layer: Layer, period, points: np.ndarray):
    dist, nx, ny = _boundary_candidates(layer, period, points)
    nearest = dist <= dist.min(axis=1, keepdims=True) + 1e-12 * max(period)
    count = nearest.sum(axis=1)
    mean = lambda f: np.where(nearest, f, 0.0).sum(axis=1) / count  # noqa: E731
    return mean(nx * nx), mean(nx * ny), mean(ny * ny)

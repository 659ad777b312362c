"""Fourier coefficients of piecewise-constant periodic cells and their Toeplitz matrices.

Conventions (workbench.core.conventions): a periodic function is
``f(r) = sum_g c(g) exp(+i g.G r)`` with ``c(g) = (1/A) int_cell f(r) exp(-i g.G r) dr``.
Harmonic ``m`` of a field has ``k_m = k_inc - m G`` ([Lange 2021, Eq. 2] sign), so the
product ``f E`` has, at harmonic ``m``, ``sum_n c(n - m) E_n``: the convolution matrix is
``C[m, n] = c(n - m)`` ([Li 1996, Eq. 3], with the order sign flipped).

Shape transforms are exact (closed forms), never a raster:
* interval: ``int_a^b exp(-i q x) dx``;
* rectangle: the product of two interval transforms;
* circle: ``2 pi R^2 J1(|q| R) / (|q| R)`` times the centre's phase ([Bracewell 2000, Ch. 13],
  the 'jinc' pair);
* polygon: by the divergence theorem, ``int_P exp(-i q.r) dA = (i/|q|^2) sum_edges
  (q.n_j) L_j exp(-i q.M_j) sinc(q.D_j / 2)``, with edge length ``L_j``, outward normal
  ``n_j``, midpoint ``M_j`` and edge vector ``D_j`` ([Lee 1983, Eq. 8], written
  with the unnormalized sinc(x) = sin(x)/x).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from scipy.special import j1

Segment = tuple[float, float, complex]  # (x0, x1, value) on [0, period)
Value = TypeVar("Value")  # what a profile holds: a permittivity, or a material (rcwa.symmetry)


# ---------------------------------------------------------------- 1D profiles


def paint_intervals(
    period: float, background: Value, intervals: Sequence[tuple[float, float, Value]]
) -> list[tuple[float, float, Value]]:
    """Piecewise-constant profile on ``[0, period)``; later intervals overwrite earlier ones.

    Intervals may cross the cell edge (they wrap periodically); each must be no wider
    than the period.
    """
    pieces: list[tuple[float, float, Value]] = []
    for x0, x1, value in intervals:
        shift = np.floor(x0 / period) * period
        a, b = x0 - shift, x1 - shift
        if b <= period:
            pieces.append((a, b, value))
        else:
            pieces.append((a, period, value))
            pieces.append((0.0, b - period, value))
    cuts = sorted({0.0, period, *(p[0] for p in pieces), *(p[1] for p in pieces)})
    segments: list[tuple[float, float, Value]] = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        if b - a <= 0.0:
            continue
        mid = 0.5 * (a + b)
        value = background
        for p0, p1, v in pieces:
            if p0 <= mid < p1:
                value = v
        if segments and segments[-1][2] == value and segments[-1][1] == a:
            segments[-1] = (segments[-1][0], b, value)
        else:
            segments.append((a, b, value))
    return segments


def interval_transform(q: np.ndarray, a: float | np.ndarray, b: float | np.ndarray) -> np.ndarray:
    """``int_a^b exp(-i q x) dx``, exact, with the q = 0 limit ``b - a``; ``q``, ``a`` and ``b``
    broadcast (several intervals at once: ``a``, ``b`` of shape (k, 1) against ``q`` of shape (g,))."""
    q = np.asarray(q, dtype=float)
    half = 0.5 * (b - a)
    return (b - a) * np.exp(-1j * q * 0.5 * (a + b)) * np.sinc(q * half / np.pi)


def profile_coefficients(segments: list[Segment], period: float, g: np.ndarray) -> np.ndarray:
    """Fourier coefficients ``c(g)`` of a piecewise-constant profile on ``[0, period)``."""
    q = 2.0 * np.pi * np.asarray(g, dtype=float) / period
    total = np.zeros(q.shape, dtype=complex)
    for a, b, value in segments:
        total += value * interval_transform(q, a, b)
    return total / period


def toeplitz(c_of_g, m: np.ndarray) -> np.ndarray:
    """Convolution matrix ``C[i, j] = c(m_j - m_i)`` for harmonic indices ``m``.

    ``c_of_g`` maps an integer array of index differences to coefficients.
    """
    diff = m[None, :] - m[:, None]
    return c_of_g(diff)


# ---------------------------------------------------------------- 2D shapes


@dataclass(frozen=True)
class Polygon2D:
    """A simple polygon (counter-clockwise after construction), possibly with holes."""

    exterior: np.ndarray  # (k, 2)
    holes: tuple[np.ndarray, ...] = ()


def _ccw(vertices: np.ndarray) -> np.ndarray:
    x, y = vertices[:, 0], vertices[:, 1]
    area2 = np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    return vertices if area2 > 0 else vertices[::-1]


def polygon_area(vertices: np.ndarray) -> float:
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * abs(float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


def polygon_transform(vertices: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
    """``int_P exp(-i q.r) dA`` of a simple polygon, exact (see the module docstring)."""
    v = _ccw(np.asarray(vertices, dtype=float))
    a, b = v, np.roll(v, -1, axis=0)
    d = b - a
    mid = 0.5 * (a + b)
    qx = np.asarray(qx, dtype=float)[..., None]
    qy = np.asarray(qy, dtype=float)[..., None]
    q2 = qx[..., 0] ** 2 + qy[..., 0] ** 2
    q_dot_n = qx * d[:, 1] - qy * d[:, 0]  # q . (outward normal * edge length)
    phase = np.exp(-1j * (qx * mid[:, 0] + qy * mid[:, 1]))
    s = np.sinc((qx * d[:, 0] + qy * d[:, 1]) / (2.0 * np.pi))
    with np.errstate(invalid="ignore", divide="ignore"):
        value = 1j / q2 * np.sum(q_dot_n * phase * s, axis=-1)
    return np.where(q2 == 0.0, polygon_area(v), value)


def rectangle_transform(center, size, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
    cx, cy = center
    sx, sy = size
    return interval_transform(qx, cx - sx / 2, cx + sx / 2) * interval_transform(qy, cy - sy / 2, cy + sy / 2)


def circle_transform(center, radius: float, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
    qx = np.asarray(qx, dtype=float)
    qy = np.asarray(qy, dtype=float)
    qr = np.hypot(qx, qy) * radius
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(qr == 0.0, 0.5, j1(qr) / np.where(qr == 0.0, 1.0, qr))
    return 2.0 * np.pi * radius**2 * ratio * np.exp(-1j * (qx * center[0] + qy * center[1]))


def region_transform(region: Polygon2D, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
    total = polygon_transform(region.exterior, qx, qy)
    for hole in region.holes:
        total = total - polygon_transform(hole, qx, qy)
    return total

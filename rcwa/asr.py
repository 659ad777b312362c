"""Adaptive spatial resolution (ASR) for 2D cells of axis-aligned rectangles [Granet 1999].

A metal block's fields vary at its edges on scales far below the period, and uniform
Fourier harmonics resolve them slowly (gold2d's T(0,0) converges like N^-1.4 with Li's
rule: docs/gold2d_convergence.md). ASR solves the same cell in stretched coordinates
``x = f(u)``, ``y = g(v)`` whose uniform harmonics crowd near every edge. Between two
consecutive edges ``a`` and ``a + L`` (in x; y alike) the stretch is

    f(u) = u - eta L / (2 pi) sin(2 pi (u - a) / L),   f'(u) = 1 - eta cos(2 pi (u - a) / L),

so every edge stays where it is, ``f'`` is continuous, and near an edge a step in u covers
``1 - eta`` of a step in x (``eta = 0``: no stretch; the sine stretch of [Granet 1999]).

Maxwell's equations keep their form in the new coordinates with ([Ward 1996], for
``J = diag(f', g', 1)``) the permittivity ``eps diag(g'/f', f'/g', f' g')``, the permeability
``diag(g'/f', f'/g', f' g')`` and the covariant tangential fields ``E_u = f' E_x``,
``E_v = g' E_y`` (h alike). Each layer is then the PQ eigenproblem of rcwa/cpp/modes.hpp
with a permeability: ``P = [[Kx Z Ky, Myy - Kx Z Kx], [Ky Z Ky - Mxx, -Ky Z Kx]]``,
``Q = [[-Kx Mzz^-1 Ky, Kx Mzz^-1 Kx - Eyy], [Exx - Ky Mzz^-1 Ky, Ky Mzz^-1 Kx]]``
(``Z = Ezz^-1``), every product factorized by [Li 1997]'s rules in (u, v), where the
edges lie on coordinate lines as before: Exx = sum over y-slabs of [[f'/eps]]_u^-1 (x)
[[g' 1_slab]]_v, Eyy likewise, Ezz = [[eps f' g']], Mxx = [[f']]^-1 (x) [[g']], Myy =
[[f']] (x) [[g']]^-1, Mzz = [[f']] (x) [[g']]. The stretch applies in every layer, so
uniform layers are solved as eigenproblems too. The half-spaces keep their plane waves:
at an interface a physical order's tangential field ``e^{i kx_m x}`` reads, in the
harmonics of u, ``A0[p, m] = <e^{i kx_m f(u)} e^{-i kx_p u}>`` and, for the covariant
component, ``A1[p, m] = <f'(u) e^{i kx_m f(u)} e^{-i kx_p u}>`` (the Rayleigh expansion
rewritten in the stretched coordinates, as [Granet 1999] does for the lamellar case).
Layers are joined bottom-up by the enhanced transmittance matrix [Moharam 1995b], which
multiplies no growing exponential.

The in-plane permittivity can instead be factorized by the normal-vector method
(``rule="nv"``, _nv_in_plane): its physical relation written in the stretched coordinates,
as adaptive coordinates carry any factorization rule [Essig 2010].

This is a dense numpy solver for convergence studies (``rule = "asr"`` and ``"asr_nv"`` in
rcwa.solve_cache): it uses no mirror sector and is not part of the tables' core.
Its ``eta = 0`` is Li's rule, or the NV rule, exactly (tests/rcwa/test_asr.py: the core's
efficiencies to 1e-10).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from rcwa.factorization import NV_GRID, _convolution, normal_products_at, nv_corrections, nv_delta
from rcwa.shapes import Rect
from rcwa.solver import _harmonics, _permittivity_lookup, incident_tangential_k
from rcwa.structure import Structure
from workbench.core.conventions import ORDER_SIGN
from workbench.core.errors import UserInputError

ASR_RULES = ("li", "nv")  # the in-plane factorizations solve_asr offers
DEFAULT_ETA = 0.9  # the stretch's strength: near an edge one u step covers 1 - eta of an x step
KZ_FLOOR = 1e-8  # |kz| of a layer mode below this is moved to it (coinciding up- and down-going modes)


@dataclass(frozen=True)
class AsrSolve:
    """Efficiencies per polarization (index 0 = s, 1 = p): ``R[i, pol]``, ``T[i, pol]`` of harmonic
    ``(m[i], n[i])`` (0 where it does not propagate)."""

    m: np.ndarray
    n: np.ndarray
    R: np.ndarray
    T: np.ndarray


@dataclass(frozen=True)
class Stretch:
    """The sine stretch ``x = f(u)`` of one axis: segments between consecutive edges, each
    with Gauss-Legendre nodes (``u``, weights ``w``, ``x = f(u)``, ``dxdu = f'(u)``)."""

    period: float
    starts: np.ndarray  # each segment's first edge (u = x there)
    lengths: np.ndarray
    u: list[np.ndarray]
    w: list[np.ndarray]
    x: list[np.ndarray]
    dxdu: list[np.ndarray]
    eta: float

    @classmethod
    def between(cls, period: float, edges: list[float], eta: float, max_order: int) -> Stretch:
        """The stretch for ``edges`` (any order, taken modulo the period); no edge: one
        unstretched segment. Nodes enough for phases up to ``max_order`` periods' harmonics."""
        cuts = np.unique(np.round(np.mod(edges, period), 12))
        if cuts.size == 0:
            cuts, eta = np.array([0.0]), 0.0
        lengths = np.diff(np.append(cuts, cuts[0] + period))
        us, ws, xs, ds = [], [], [], []
        for a, length in zip(cuts, lengths, strict=True):
            # The integrands' phase runs through at most 2 pi (max_order + 2) (1 + eta) L / period.
            phase = 2 * math.pi * (max_order + 2) * (1 + eta) * length / period
            t, weights = np.polynomial.legendre.leggauss(int(40 + phase))
            s = 0.5 * length * (t + 1.0)
            us.append(a + s)
            ws.append(0.5 * length * weights)
            xs.append(a + s - eta * length / (2 * math.pi) * np.sin(2 * math.pi * s / length))
            ds.append(1.0 - eta * np.cos(2 * math.pi * s / length))
        return cls(period, cuts, lengths, us, ws, xs, ds, eta)

    def map(self, u: np.ndarray) -> np.ndarray:
        """``x = f(u)`` at any ``u`` in [0, period) (the stretch of the segment each u lies in)."""
        segment = (np.searchsorted(self.starts, u, side="right") - 1) % self.starts.size
        s = np.mod(u - self.starts[segment], self.period)
        length = self.lengths[segment]
        return np.mod(self.starts[segment] + s - self.eta * length / (2 * math.pi) * np.sin(2 * math.pi * s / length),
                      self.period)

    def centres(self) -> np.ndarray:
        return np.mod(self.starts + 0.5 * self.lengths, self.period)

    def segment_coefficients(self, orders: np.ndarray) -> np.ndarray:
        """Row l: the Fourier coefficients over u of ``f'(u)`` on segment l alone,
        ``(1 / period) int_l f'(u) e^{-i 2 pi k u / period} du`` for ``k`` in ``orders``; a profile
        ``c_l f'(u)`` has ``c @ rows``."""
        q = 2 * math.pi * orders / self.period
        return np.array([np.exp(-1j * np.outer(q, u)) @ (w * d) for u, w, d in zip(self.u, self.w, self.dxdu, strict=True)]
                        ) / self.period

    def rayleigh(self, k_physical: np.ndarray, covariant: bool) -> np.ndarray:
        """``A[p, m]``: harmonic p (over u) of the physical wave ``e^{i k_m x}``, times ``f'`` if
        ``covariant`` (A1 of the module docstring, else A0); ``k`` in rad per period unit."""
        u = np.concatenate(self.u)
        x = np.concatenate(self.x)
        w = np.concatenate(self.w) * (np.concatenate(self.dxdu) if covariant else 1.0)
        return (np.exp(-1j * np.outer(k_physical, u)) * w) @ np.exp(1j * np.outer(x, k_physical)) / self.period


def _toeplitz(c: np.ndarray, size: int) -> np.ndarray:
    """``T[p, m] = c[m - p]`` for p, m in -M..M (``size = 2M + 1``), c listed for -2M..2M: harmonic m
    has ``kx_m = kx_0 + ORDER_SIGN m 2 pi / period`` (ORDER_SIGN = -1), as rcwa.factorization's
    convolution matrices."""
    idx = np.arange(size)
    return c[idx[None, :] - idx[:, None] + size - 1]


def _kron(a: np.ndarray, b: np.ndarray, im: np.ndarray, jn: np.ndarray) -> np.ndarray:
    """The 2D operator ``a (x) b`` on harmonics (m, n): entry ``a[m_i, m_j] b[n_i, n_j]``."""
    return a[im[:, None], im[None, :]] * b[jn[:, None], jn[None, :]]


def _cell_permittivity(layer, period, eps_of, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """The layer's permittivity at the points (xs[i], ys[j]): later shapes over earlier ones."""
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    eps = np.full(X.shape, complex(eps_of(layer.material)))
    for shape in layer.shapes_2d:
        inside = np.zeros(X.shape, dtype=bool)
        for dx in (-period[0], 0.0, period[0]):
            for dy in (-period[1], 0.0, period[1]):
                inside |= shapely.contains_xy(shape.outline(), X + dx, Y + dy)
        eps[inside] = complex(eps_of(shape.material))
    return eps


def _check_rectangles(structure: Structure) -> None:
    if structure.dimension != 2:
        raise UserInputError("adaptive spatial resolution is built for 2D cells", file=structure.source,
                             field="period", expected="two periods", got=structure.period)
    for i, layer in enumerate(structure.layers):
        for j, shape in enumerate(layer.shapes_2d):
            if not isinstance(shape, Rect):
                raise UserInputError("adaptive spatial resolution needs axis-aligned rectangles", file=structure.source,
                                     field=f"layers[{i}].shapes[{j}]", expected="a rect", got=type(shape).__name__)


@dataclass(frozen=True)
class _Axes:
    """Both stretches and the 1D operators every layer shares."""

    sx: Stretch
    sy: Stretch
    im: np.ndarray  # harmonic i's m as an index into -Mx..Mx
    jn: np.ndarray
    size_x: int
    size_y: int
    cx: np.ndarray  # sx.segment_coefficients over -2Mx..2Mx, computed once for every layer
    cy: np.ndarray

    @classmethod
    def of(cls, sx: Stretch, sy: Stretch, im: np.ndarray, jn: np.ndarray, size_x: int, size_y: int) -> _Axes:
        mx, my = size_x // 2, size_y // 2
        return cls(sx, sy, im, jn, size_x, size_y, sx.segment_coefficients(np.arange(-2 * mx, 2 * mx + 1)),
                   sy.segment_coefficients(np.arange(-2 * my, 2 * my + 1)))

    def toeplitz_x(self, per_segment: np.ndarray) -> np.ndarray:
        """``[[c_l f' 1_l]]`` summed over the x segments l (``per_segment`` = c)."""
        return _toeplitz(per_segment @ self.cx, self.size_x)

    def toeplitz_y(self, per_segment: np.ndarray) -> np.ndarray:
        return _toeplitz(per_segment @ self.cy, self.size_y)


def _layer_matrices(eps: np.ndarray, axes: _Axes):
    """Exx, Eyy, Z = Ezz^-1, Mxx, Myy, Mzz^-1 of a layer whose permittivity on segment pair
    (i, j) is eps[i, j] ([Li 1997]'s rules in the stretched coordinates)."""
    kr = lambda a, b: _kron(a, b, axes.im, axes.jn)  # noqa: E731
    nx, ny = eps.shape
    unit_x, unit_y = np.eye(nx), np.eye(ny)
    fx = [axes.toeplitz_x(unit_x[i]) for i in range(nx)]  # [[f' 1_i]]
    gy = [axes.toeplitz_y(unit_y[j]) for j in range(ny)]
    exx = sum(kr(np.linalg.inv(axes.toeplitz_x(1.0 / eps[:, j])), gy[j]) for j in range(ny))
    eyy = sum(kr(fx[i], np.linalg.inv(axes.toeplitz_y(1.0 / eps[i, :]))) for i in range(nx))
    ezz = sum(eps[i, j] * kr(fx[i], gy[j]) for i in range(nx) for j in range(ny))
    F, G = sum(fx), sum(gy)
    Fi, Gi = np.linalg.inv(F), np.linalg.inv(G)
    return exx, eyy, np.linalg.inv(ezz), kr(Fi, G), kr(F, Gi), kr(Fi, Gi)


def _nv_in_plane(layer, period, eps_of, h, axes: _Axes) -> tuple[np.ndarray, ...]:
    """Exx, Exy, Eyx, Eyy by the normal-vector method [Schuster 2007] in the stretched
    coordinates. The physical relation ``D = (E - Delta [[n n^T]]) E`` (rcwa.factorization.nv_rule)
    is taken over unchanged, its factorization being about which functions jump, which a
    change of coordinates keeps: with ``E_x = E_u / f'``, ``E_y = E_v / g'`` and ``D^u = g' D_x``,
    ``D^v = f' D_y`` [Ward 1996], Exx = [[g']] (E - Delta [[nx^2]]) [[f']]^-1, Exy = -[[g']] Delta
    [[nx ny]] [[g']]^-1, and y alike. ``[[eps]]`` and ``[[1/eps]]`` over (u, v) are those over (x, y):
    every edge stays on its coordinate line. The normal field is the physical one,
    ``n(f(u), g(v))``, sampled on the uniform (u, v) grid."""
    cell = (period[0], period[1])
    mx, my = axes.size_x // 2, axes.size_y // 2
    E, delta = nv_delta(layer, cell, eps_of, h)
    centres = (np.arange(NV_GRID) + 0.5) / NV_GRID
    products = normal_products_at(layer, cell, axes.sx.map(centres * cell[0]), axes.sy.map(centres * cell[1]),
                                  2 * mx, 2 * my)
    nxx, nxy, nyy = (_convolution(c, 2 * mx, 2 * my, h) for c in products)
    dxx, dxy, dyy = nv_corrections(delta, nxx, nxy, nyy)
    kr = lambda a, b: _kron(a, b, axes.im, axes.jn)  # noqa: E731
    F, G = axes.toeplitz_x(np.ones(axes.sx.starts.size)), axes.toeplitz_y(np.ones(axes.sy.starts.size))
    ix, iy = np.eye(axes.size_x), np.eye(axes.size_y)
    g_, f_ = kr(ix, G), kr(F, iy)
    fi, gi = kr(np.linalg.inv(F), iy), kr(ix, np.linalg.inv(G))
    return g_ @ (E - dxx) @ fi, -g_ @ dxy @ gi, -f_ @ dxy @ fi, f_ @ (E - dyy) @ gi


def _layer_modes(eps: np.ndarray, axes: _Axes, kx: np.ndarray, ky: np.ndarray,
                 in_plane: tuple[np.ndarray, ...] | None = None):
    """W, V and kz of a layer (modes.hpp's conventions: psi = W e^{-+ i kz z}, phi = -+ V ...);
    ``in_plane``: Exx, Exy, Eyx, Eyy of another rule in place of Li's (_nv_in_plane)."""
    exx, eyy, Z, mxx, myy, mzz_inv = _layer_matrices(eps, axes)
    exy = eyx = np.zeros_like(exx)
    if in_plane is not None:
        exx, exy, eyx, eyy = in_plane
    kxc, kyc, kxr, kyr = kx[:, None], ky[:, None], kx[None, :], ky[None, :]
    P = np.block([[kxc * Z * kyr, myy - kxc * Z * kxr], [kyc * Z * kyr - mxx, -kyc * Z * kxr]])
    Q = np.block([[-kxc * mzz_inv * kyr - eyx, kxc * mzz_inv * kxr - eyy],
                  [exx - kyc * mzz_inv * kyr, kyc * mzz_inv * kxr + exy]])
    kz2, W = np.linalg.eig(P @ Q)
    kz = np.sqrt(kz2.astype(complex))
    kz = np.where(kz.imag < 0, -kz, kz)
    kz = np.where(np.abs(kz) < KZ_FLOOR, KZ_FLOOR, kz)
    return W, (Q @ W) / kz[None, :], kz


def _half_space_V(eps: complex, kx: np.ndarray, ky: np.ndarray, kz: np.ndarray) -> np.ndarray:
    """V = Q / kz of a uniform medium, per order (rcwa/cpp/modes.hpp's uniform_modes)."""
    return np.block([[np.diag(-kx * ky / kz), np.diag((kx**2 - eps) / kz)],
                     [np.diag((eps - ky**2) / kz), np.diag(kx * ky / kz)]])


def _outgoing_kz(eps: complex, kx: np.ndarray, ky: np.ndarray) -> np.ndarray:
    kz = np.sqrt(complex(eps) - kx**2 - ky**2 + 0j)
    return np.where(kz.imag < 0, -kz, kz)


def solve_asr(structure: Structure, wavelength_nm: float, theta_deg: float, phi_deg: float, orders: int,
              eta: float = DEFAULT_ETA, rule: str = "li") -> AsrSolve:
    """Every order's R and T for s and p at ``orders x orders`` harmonics (module docstring);
    ``rule``: the in-plane permittivity's factorization, ``li`` or ``nv`` (_nv_in_plane)."""
    _check_rectangles(structure)
    if not 0.0 <= eta < 1.0:
        raise UserInputError("the stretch's strength must be in [0, 1)", field="eta", expected="0 <= eta < 1", got=eta)
    if rule not in ASR_RULES:
        raise UserInputError("unknown factorization rule for adaptive spatial resolution", field="factorization",
                             expected=f"one of {ASR_RULES}", got=rule)
    wl_um = wavelength_nm / 1000.0
    k0 = 2 * math.pi / wl_um
    eps_of = _permittivity_lookup(structure, float(wavelength_nm))
    eps1, eps3 = eps_of(structure.superstrate).real, eps_of(structure.substrate)
    h, dkx, dky, zero = _harmonics(structure.period, (orders, orders), wl_um)
    theta, phi = math.radians(theta_deg), math.radians(phi_deg)
    kx0, ky0 = incident_tangential_k(math.sqrt(eps1), theta, phi)
    kx, ky = kx0 + dkx, ky0 + dky
    M = orders // 2
    layers = [layer for layer in structure.layers if layer.thickness > 0]
    edges = [[e for layer in layers for s in layer.shapes_2d for e in s.edges_along(a)] for a in (0, 1)]
    sx = Stretch.between(structure.period[0], edges[0], eta, 2 * M)
    sy = Stretch.between(structure.period[1], edges[1], eta, 2 * M)
    axes = _Axes.of(sx, sy, h.m + M, h.n + M, orders, orders)
    # The half-spaces' plane waves in the stretched harmonics (physical wave numbers per um).
    kxs = k0 * kx0 + ORDER_SIGN * 2 * math.pi / structure.period[0] * np.arange(-M, M + 1)
    kys = k0 * ky0 + ORDER_SIGN * 2 * math.pi / structure.period[1] * np.arange(-M, M + 1)
    ax0, ax1 = sx.rayleigh(kxs, False), sx.rayleigh(kxs, True)
    ay0, ay1 = sy.rayleigh(kys, False), sy.rayleigh(kys, True)
    zeros = np.zeros((h.m.size, h.m.size), dtype=complex)
    T_field = np.block([[_kron(ax1, ay0, axes.im, axes.jn), zeros], [zeros, _kron(ax0, ay1, axes.im, axes.jn)]])
    kz1, kz3 = _outgoing_kz(eps1, kx, ky), _outgoing_kz(eps3, kx, ky)
    V1, V3 = _half_space_V(eps1, kx, ky, kz1), _half_space_V(eps3, kx, ky, kz3)
    f, g = T_field, -T_field @ V3
    down: list[np.ndarray] = []  # per layer, bottom first: a layer's transmitted amplitudes from its own
    for layer in reversed(layers):
        eps = _cell_permittivity(layer, structure.period, eps_of, sx.centres(), sy.centres())
        in_plane = _nv_in_plane(layer, structure.period, eps_of, h, axes) if rule == "nv" and layer.shapes_2d else None
        W, V, kz = _layer_modes(eps, axes, kx, ky, in_plane)
        X = np.exp(1j * kz * k0 * layer.thickness)
        Wf, Vg = np.linalg.solve(W, f), np.linalg.solve(V, g)
        A, B = 0.5 * (Wf - Vg), 0.5 * (Wf + Vg)
        A_inv_X = np.linalg.solve(A, np.diag(X))
        XBAX = X[:, None] * (B @ A_inv_X)
        f, g = W @ (np.eye(X.size) + XBAX), V @ (XBAX - np.eye(X.size))
        down.append(A_inv_X)
    n = h.m.size
    incident = np.zeros((2 * n, 2), dtype=complex)
    incident[[zero, n + zero], 0] = -math.sin(phi), math.cos(phi)  # s
    incident[[zero, n + zero], 1] = math.cos(theta) * math.cos(phi), math.cos(theta) * math.sin(phi)  # p
    system = np.block([[T_field, -f], [T_field @ V1, -g]])
    rhs = np.vstack([-T_field @ incident, T_field @ V1 @ incident])
    solution = np.linalg.solve(system, rhs)
    r, a = solution[:2 * n], solution[2 * n:]
    for step in reversed(down):
        a = step @ a
    R = _flux(r, kx, ky, kz1, +1) / kz1[zero].real
    T = _flux(a, kx, ky, kz3, -1) / kz1[zero].real
    return AsrSolve(h.m, h.n, R, T)


def _flux(tangential: np.ndarray, kx: np.ndarray, ky: np.ndarray, kz: np.ndarray, sign: int) -> np.ndarray:
    """Re(kz) |E|^2 of each order's plane wave (E_z from k . E = 0; ``sign`` of its k_z)."""
    n = kx.size
    ex, ey = tangential[:n], tangential[n:]
    ez = -(kx[:, None] * ex + ky[:, None] * ey) / (sign * kz[:, None])
    power = np.abs(ex) ** 2 + np.abs(ey) ** 2 + np.abs(ez) ** 2
    propagating = (np.abs(kz.imag) < 1e-12) & (kz.real > 0)
    return np.where(propagating[:, None], kz.real[:, None] * power, 0.0)

"""Solve one benchmark case with an open-source RCWA peer and print the result as JSON.

Runs INSIDE the separate ``.venv-bench`` environment (see ``setup_peers.sh``); it imports
nothing from this project, so the peers' pinned numpy/scipy never meet ours.

Usage::

    .venv-bench/bin/python benchmarks/peer_runner.py CASE.json [--peer meent|grcwa|fmmax]
                                                          [--repeats K]

With ``--serve`` it warms up once and then times one round per line read from stdin (the
line is the number of repeats), printing one JSON object per line: bench_solve.py uses it
to interleave rounds with its own timings without paying the warm-up (fmmax's jit
compilation: seconds) per round.

CASE.json is one benchmark case (format in ``bench_solve.py``; its ``"structure"`` is the
project's structure-file format as a dict). The output is one JSON object on stdout::

    {"peer": "meent", "version": "0.13.2", "seconds_per_solve": ..., "seconds_s": ..,
     "seconds_p": .., "repeats": K, "formulation": "...", "orders": [{"m": .., "n": ..,
     "R_s": .., "R_p": .., "T_s": .., "T_p": ..}, ...], "totals": {...}}

``seconds_per_solve`` is the median CPU time of this process (``time.process_time``, the
same measure bench_solve.py uses for ours), over K repeats after one warm-up, of
everything needed to get the efficiencies of BOTH incident polarizations for the case
(building the peer's model and Fourier matrices included); ``seconds_s`` / ``seconds_p``
the same for one incident polarization, by the peer's fastest route to it (meent: its
TE-only / TM-only 1D solver in classical mount, else its one solve; grcwa and fmmax: one
excitation). The three are interleaved within each repeat. Everything runs on one thread
(OMP/OPENBLAS/MKL threads = 1, XLA's CPU client single-threaded). fmmax's solve is
``jax.jit``-compiled once in the warm-up, as its users run it.

Conventions (the project's, ``workbench/core/conventions.py``; every mapping below was checked
against an independent reference by ``check_peer_conventions.py``):

* exp(-i omega t), Im(n) > 0 for lossy media.
* z points into the superstrate; the incident wave travels toward -z with tangential wave
  vector k0 n_sup (sin theta cos phi, sin theta sin phi).
* Order m (and n) has k_x,m = k_x,inc - m 2 pi / Lambda_x (k_y,n = k_y,inc - n 2 pi /
  Lambda_y), [Lange 2021, Eq. 2].
* s: E perpendicular to the plane of incidence (TE); p: TM.
* Efficiency: fraction of incident power through a plane z = const, summed over both
  output polarizations. ``R_s`` is the efficiency of a reflected order for s incidence,
  ``T_p`` of a transmitted order for p incidence, and so on.

An order is listed when it propagates in the superstrate or in the substrate (for a lossy
medium: when Re(n^2) > |k_t|^2 / k0^2). ``totals`` sums over every order, listed or not,
so that the power entering a lossy substrate is still accounted for.
"""

from __future__ import annotations

import os

# Single-threaded BLAS/LAPACK: must be set before numpy is imported.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
             "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"
os.environ["XLA_FLAGS"] = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
os.environ.setdefault("JAX_PLATFORMS", "cpu")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from fractions import Fraction  # noqa: E402

import numpy as np  # noqa: E402

PEERS = ("meent", "grcwa", "fmmax")
# Incident polarizations a timed call answers: one of them, or both.
POL_SETS = {"s": ("s",), "p": ("p",), "both": ("s", "p")}

# Largest uniform raster (cells per period, per axis) used to represent the stripes/rectangles
# exactly on the peer's grid. meent's continuous-Fourier-series path then merges equal
# columns, so its Fourier coefficients are exact; grcwa uses a discrete FFT of the grid.
MAX_EXACT_CELLS_1D = 4096
MAX_EXACT_CELLS_2D = 512
# grcwa samples eps on a grid and takes its DFT: a fine grid keeps the aliasing error of the
# step function's coefficients small (about 1e-3 relative at |m| = 30 with 4096 cells).
GRCWA_CELLS_1D = 4096
GRCWA_CELLS_2D = 256


# --------------------------------------------------------------------------------------------
# Case parsing
# --------------------------------------------------------------------------------------------


class CaseError(ValueError):
    """A case file that the runner cannot read."""


def complex_index(material, where: str) -> complex:
    """Complex refractive index n + i k (exp(-i omega t) convention) of a material spec.

    Accepts a number or ``{"n": .., "k": ..}``; named library materials and CSV files are
    the project's business and must be resolved to numbers before a case reaches a peer.
    """
    if isinstance(material, (int, float)):
        return complex(float(material), 0.0)
    if isinstance(material, dict) and "n" in material:
        return complex(float(material["n"]), float(material.get("k", 0.0)))
    raise CaseError(f"{where}: expected a number or {{'n': .., 'k': ..}}, got {material!r}")


@dataclass
class Shape:
    index: complex
    x: tuple[float, float]  # [x0, x1) in micrometres
    y: tuple[float, float] | None = None  # None for 1D

    def extent(self, axis: int) -> tuple[float, float]:
        """``[lo, hi)`` along x (axis 0) or y (axis 1, which only a 2D shape has)."""
        span = self.x if axis == 0 else self.y
        if span is None:
            raise CaseError("a 1D shape has no extent along y")
        return span


@dataclass
class Layer:
    thickness: float
    background: complex
    shapes: list[Shape] = field(default_factory=list)


@dataclass
class Case:
    name: str
    wavelength_um: float
    theta_rad: float
    phi_rad: float
    n_orders: tuple[int, ...]  # (Nx,) or (Nx, Ny): total orders per axis, odd
    period: tuple[float, ...]
    n_sup: complex
    n_sub: complex
    layers: list[Layer]

    @property
    def is_2d(self) -> bool:
        return len(self.period) == 2

    @property
    def half_orders(self) -> tuple[int, int]:
        hx = (self.n_orders[0] - 1) // 2
        hy = (self.n_orders[1] - 1) // 2 if self.is_2d else 0
        return hx, hy


def parse_case(data: dict) -> Case:
    """Read a case dict (see module docstring of bench_solve.py) into a :class:`Case`."""
    try:
        st = data["structure"]
        period = tuple(float(p) for p in st["period"])
        if len(period) not in (1, 2):
            raise CaseError(f"structure.period: expected 1 or 2 values, got {st['period']!r}")
        orders = data["orders"]
        orders = (int(orders),) if isinstance(orders, (int, float)) else tuple(int(o) for o in orders)
        if len(orders) != len(period):
            raise CaseError(f"orders: expected {len(period)} value(s) to match the period, got {orders!r}")
        if any(o < 1 or o % 2 == 0 for o in orders):
            raise CaseError(f"orders: expected odd totals (2N+1), got {orders!r}")
        layers = []
        for i, lay in enumerate(st.get("layers", [])):
            bg = complex_index(lay["material"], f"structure.layers[{i}].material")
            shapes = []
            for j, sh in enumerate(lay.get("shapes", []) or []):
                where = f"structure.layers[{i}].shapes[{j}]"
                idx = complex_index(sh["material"], where + ".material")
                if len(period) == 1:
                    if "x" not in sh:
                        raise CaseError(f"{where}: a 1D shape needs 'x': [x0, x1]")
                    x0, x1 = (float(v) for v in sh["x"])
                    shapes.append(Shape(idx, (x0, x1)))
                else:
                    if "rect" not in sh:
                        raise CaseError(f"{where}: only 'rect' shapes are supported by the peers")
                    (cx, cy), (sx, sy) = sh["rect"]["center"], sh["rect"]["size"]
                    shapes.append(Shape(idx, (cx - sx / 2, cx + sx / 2), (cy - sy / 2, cy + sy / 2)))
            layers.append(Layer(float(lay["thickness"]), bg, shapes))
        return Case(
            name=str(data.get("name", "case")),
            wavelength_um=float(data["wavelength_nm"]) / 1000.0,
            theta_rad=math.radians(float(data["theta_deg"])),
            phi_rad=math.radians(float(data.get("phi_deg", 0.0))),
            n_orders=orders,
            period=period,
            n_sup=complex_index(st["superstrate"], "structure.superstrate"),
            n_sub=complex_index(st["substrate"], "structure.substrate"),
            layers=layers,
        )
    except KeyError as exc:
        raise CaseError(f"missing field {exc.args[0]!r}") from None


# --------------------------------------------------------------------------------------------
# Rasterization of stripes / rectangles
# --------------------------------------------------------------------------------------------


def _cells_for_exact_grid(fractions: list[float], max_cells: int) -> int | None:
    """Smallest N <= max_cells such that every fraction (of a period) is a multiple of 1/N."""
    den = 1
    for f in fractions:
        fr = Fraction(f).limit_denominator(max_cells)
        if abs(float(fr) - f) > 1e-12:
            return None
        den = den * fr.denominator // math.gcd(den, fr.denominator)
        if den > max_cells:
            return None
    return den


def _axis_cells(case: Case, axis: int, max_cells: int, fallback: int) -> tuple[int, bool]:
    fr = []
    for lay in case.layers:
        for sh in lay.shapes:
            lo_hi = sh.extent(axis)
            fr += [(v / case.period[axis]) % 1.0 for v in lo_hi]
    n = _cells_for_exact_grid(fr, max_cells) if fr else 1
    if n is None:
        return fallback, False
    return max(n, 1), True


def _cover(lo: float, hi: float, period: float, n: int) -> np.ndarray:
    """Boolean mask of the n cells (centres at (i + 1/2) period / n) inside [lo, hi), periodic."""
    centres = (np.arange(n) + 0.5) * period / n
    width = hi - lo
    if width >= period:
        return np.ones(n, dtype=bool)
    return ((centres - lo) % period) < width


def rasterize(case: Case, nx: int, ny: int) -> np.ndarray:
    """Complex index on a (layers, ny, nx) raster; row iy covers y in [iy, iy+1) Ly/ny.

    Shapes are painted in order, so a later shape covers an earlier one.
    """
    out = np.empty((len(case.layers), ny, nx), dtype=complex)
    for li, lay in enumerate(case.layers):
        out[li] = lay.background
        for sh in lay.shapes:
            mx = _cover(sh.x[0], sh.x[1], case.period[0], nx)
            if case.is_2d:
                my = _cover(*sh.extent(1), case.period[1], ny)
            else:
                my = np.ones(ny, dtype=bool)
            out[li][np.outer(my, mx)] = sh.index
    return out


# --------------------------------------------------------------------------------------------
# Order bookkeeping
# --------------------------------------------------------------------------------------------


def tangential_k(case: Case, m: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(k_x, k_y) / k0 of orders (m, n) in the project's convention."""
    s = case.n_sup.real * math.sin(case.theta_rad)
    kx = s * math.cos(case.phi_rad) - m * case.wavelength_um / case.period[0]
    if case.is_2d:
        ky = s * math.sin(case.phi_rad) - n * case.wavelength_um / case.period[1]
    else:
        ky = s * math.sin(case.phi_rad) + 0 * n
    return kx, ky


def propagating(index: complex, kt2: np.ndarray) -> np.ndarray:
    return (index * index).real - kt2 > 0


def build_output(case: Case, eff: dict[str, np.ndarray]) -> tuple[list[dict], dict]:
    """Turn efficiency arrays indexed [n + hy, m + hx] (OUR order indices) into the order list."""
    hx, hy = case.half_orders
    mm, nn = np.meshgrid(np.arange(-hx, hx + 1), np.arange(-hy, hy + 1))
    kx, ky = tangential_k(case, mm, nn)
    kt2 = kx * kx + ky * ky
    keep = propagating(case.n_sup, kt2) | propagating(case.n_sub, kt2)
    orders = []
    for iy, ix in zip(*np.nonzero(keep), strict=True):
        orders.append({
            "m": int(mm[iy, ix]),
            "n": int(nn[iy, ix]),
            **{key: float(eff[key][iy, ix]) for key in ("R_s", "R_p", "T_s", "T_p")},
        })
    orders.sort(key=lambda o: (o["n"], o["m"]))
    totals = {key: float(np.sum(eff[key])) for key in ("R_s", "R_p", "T_s", "T_p")}
    return orders, totals


# --------------------------------------------------------------------------------------------
# meent
# --------------------------------------------------------------------------------------------


def meent_version() -> str:
    import meent

    return str(meent.__version__)


_MEENT_PATCHED = False


def _meent_outgoing_kz(n_medium, kx, ky):
    """kz / k0 of the outgoing wave in meent's exp(+j omega t) convention: Im(kz) <= 0.

    meent 0.13.2 takes the principal square root and then conjugates it. That picks the
    right branch for lossless media (evanescent -> -i|kz|), but for a lossy medium
    (eps = (n - ik)^2) it returns the conjugate of the physical root; the p/TM boundary
    terms, which divide that kz by the unconjugated n^2, are then wrong: for an opaque metal
    substrate meent gives Rp = 1.31 (Fresnel: 0.91) and a negative Tp. Choosing the branch
    directly gives the same numbers as before for lossless media and the right ones for
    lossy media (checked against Fresnel by check_peer_conventions.py).
    """
    kz = np.sqrt((n_medium ** 2 - kx ** 2 - ky.reshape((-1, 1)) ** 2).astype(complex))
    return np.where(kz.imag > 0, -kz, kz).flatten()


def _patch_meent() -> None:
    """Replace the kz branch choice of meent's substrate/superstrate set-up (see above).

    The replacements are the bodies of ``transfer_1d_conical_1`` and ``transfer_2d_1`` (the
    two are identical in meent 0.13.2) and of ``transfer_1d_1`` (the classical-mount TE/TM
    solver's) with the branch chosen by :func:`_meent_outgoing_kz`; the cost is unchanged.
    """
    global _MEENT_PATCHED
    if _MEENT_PATCHED:
        return
    from meent.on_numpy.emsolver import _base

    def set_up_half_spaces(kx, ky, n_top, n_bot, type_complex=np.complex128):
        ff_xy = len(kx) * len(ky)
        eye = np.eye(ff_xy, dtype=type_complex)
        zero = np.zeros((ff_xy, ff_xy), dtype=type_complex)
        kz_top = _meent_outgoing_kz(n_top, kx, ky)
        kz_bot = _meent_outgoing_kz(n_bot, kx, ky)
        varphi = np.arctan(ky.reshape((-1, 1)) / kx).flatten()
        Kz_bot = np.diag(kz_bot)
        big_F = np.block([[eye, zero], [zero, 1j * Kz_bot / (n_bot ** 2)]])
        big_G = np.block([[1j * Kz_bot, zero], [zero, eye]])
        big_T = np.eye(2 * ff_xy, dtype=type_complex)
        return kz_top, kz_bot, varphi, big_F, big_G, big_T

    def set_up_half_spaces_te_tm(pol, kx, n_top, n_bot, type_complex=np.complex128):
        # meent's classical-mount TE/TM solver (transfer_1d_1) with the same branch choice
        eye = np.eye(len(kx), dtype=type_complex)
        kz_top = _meent_outgoing_kz(n_top, kx, np.zeros(1))
        kz_bot = _meent_outgoing_kz(n_bot, kx, np.zeros(1))
        G = 1j * np.diag(kz_bot if pol == 0 else kz_bot / (n_bot ** 2))
        return kz_top, kz_bot, eye, G, eye.copy()

    _base.transfer_1d_conical_1 = set_up_half_spaces
    _base.transfer_2d_1 = set_up_half_spaces
    _base.transfer_1d_1 = set_up_half_spaces_te_tm
    _MEENT_PATCHED = True


def solve_meent(case: Case, raster: np.ndarray, pols: tuple[str, ...] = ("s", "p")) -> dict[str, np.ndarray]:
    """The polarizations ``pols`` with meent's numpy backend; arrays indexed [n + hy, m + hx] (ours).

    meent (0.13) conventions, each checked by ``check_peer_conventions.py``:

    * it works in exp(+j omega t), so a lossy index is n - i k: every index is conjugated;
    * its order index p has k_x = k_x,inc + p lambda / Lambda_x: p = -m (same for y);
    * raster rows: meent flips the raster upside down (``cell_compression``), so the row
      that covers y in [iy, iy+1) Ly/Ny is stored at row Ny-1-iy;
    * theta, phi: as ours (tangential k = n_top sin theta (cos phi, sin phi));
      the top medium is the incidence side and ``thickness[0]`` is the top layer;
    * ``res_te_inc`` / ``res_tm_inc`` are s / p incidence (w.r.t. the plane of incidence);
    * meent's kz branch is wrong for a lossy substrate in p: patched, see :func:`_patch_meent`;
      a lossless index is passed as n + 0j (meent's classical-mount TE/TM solver takes the
      wrong substrate k_z branch for n - 0j: P2's T(-1) = 0.31 instead of 0.12, issue 17);
    * one polarization in classical mount (1D, phi = 0): ``phi=None`` and ``pol`` 0 (TE) or
      1 (TM) select meent's TE-only / TM-only solver (half the work of its conical one);
      otherwise meent solves both in one call whatever is asked.

    Factorization (``fourier_type=1``: continuous Fourier series of the piecewise-constant
    raster, exact): 1D conical -- [Li 1996] inverse rule for eps_x, Laurent for eps_y and for
    1/eps_z (the same as ours); 2D -- [Li 1997]'s rules on the staircase cells, but nested
    the other way round from ours (meent's ``cfs2d``: eps_x = [[ [[eps]]_y^-1 ]]_x^-1, the
    Laurent rule along y inside and the inverse rule along x outside; ours applies the
    inverse rule along x inside each y-slab, then Laurent along y; eps_y mirrored).
    """
    from meent import call_mee

    _patch_meent()
    hx, hy = case.half_orders
    ucell = np.conj(raster[:, ::-1, :])  # n - ik, rows flipped (see docstring)
    if case.is_2d and ucell.shape[1] == 1:
        ucell = np.repeat(ucell, 2, axis=1)  # a 1-row raster would select meent's 1D solver
    single = len(pols) == 1 and not case.is_2d and case.phi_rad == 0.0
    mee = call_mee(
        backend=0,
        ucell=ucell,
        n_top=_meent_index(case.n_sup),
        n_bot=_meent_index(case.n_sub),
        theta=case.theta_rad,
        phi=None if single else case.phi_rad,  # not None: the general (conical) 1D formulation
        fto=[hx, hy],
        period=list(case.period) if case.is_2d else [case.period[0], 1.0],
        wavelength=case.wavelength_um,
        thickness=[lay.thickness for lay in case.layers],
        fourier_type=1,
        pol=(0 if pols[0] == "s" else 1) if single else 0,
    )
    res = mee.conv_solve()
    out = {}
    subs = ((pols[0], res.res),) if single else (("s", res.res_te_inc), ("p", res.res_tm_inc))
    for pol, sub in subs:
        # meent index p runs -h..h along each axis and equals -(our index): reverse both axes.
        out["R_" + pol] = np.asarray(sub.de_ri, dtype=float).reshape(2 * hy + 1, 2 * hx + 1)[::-1, ::-1]
        out["T_" + pol] = np.asarray(sub.de_ti, dtype=float).reshape(2 * hy + 1, 2 * hx + 1)[::-1, ::-1]
    return out


def _meent_index(index: complex) -> complex:
    """An index in meent's exp(+j omega t) convention: n - ik, and n + 0j when lossless."""
    return complex(index.real, 0.0) if index.imag == 0.0 else complex(np.conj(index))


MEENT_FORMULATION = {
    1: "Moharam 1995 conical TMM + Li 1996 inverse rule (eps_x), exact continuous Fourier series",
    2: ("Li 1997 rules nested the other way round (eps_x: Laurent along y inside, inverse rule along x "
        "outside; eps_y mirrored), exact continuous Fourier series"),
}


# --------------------------------------------------------------------------------------------
# grcwa
# --------------------------------------------------------------------------------------------


def grcwa_version() -> str:
    import grcwa

    return str(grcwa.__version__)


def solve_grcwa(case: Case, raster: np.ndarray, pols: tuple[str, ...] = ("s", "p")) -> dict[str, np.ndarray]:
    """The polarizations ``pols`` (one excitation each) with grcwa (numpy backend); arrays indexed [n + hy, m + hx] (ours).

    grcwa (0.1.2) conventions, each checked by ``check_peer_conventions.py``:

    * exp(-i omega t) like ours (eps = (n + ik)^2), c = 1, freq = 1 / lambda;
    * its layers are stacked along its +z from the incidence side, i.e. its z is our -z: a
      mirror of the whole problem, which leaves efficiencies of isotropic media unchanged,
      so x, y, theta, phi and the shapes are passed as they are;
    * its reciprocal index G has k_x = k_x,inc + G_1 2 pi / Lambda_x: G_1 = -m (same for y);
    * ``MakeExcitationPlanewave(p_amp, p_phase, s_amp, s_phase)``: s_amp=1 is s incidence.

    The order set is forced to the full rectangle |m| <= hx, |n| <= hy (grcwa's own circular
    truncation would drop the outermost ring). Factorization: grcwa has no Li rules --
    Laurent's rule for the in-plane eps and the inverse of the Laurent eps for 1/eps_z, with
    eps coefficients from the DFT of a sampled grid -- so it converges more slowly for p/TM
    and metals, and does not match our formulation.
    """
    import grcwa
    import grcwa.rcwa as grcwa_rcwa

    hx, hy = case.half_orders
    gx, gy = np.meshgrid(np.arange(-hx, hx + 1), np.arange(-hy, hy + 1))
    G = np.stack([-gx.ravel(), -gy.ravel()], axis=1).astype(int)  # G index = -(our index)
    original = grcwa_rcwa.Lattice_getG
    grcwa_rcwa.Lattice_getG = lambda nG, Lk1, Lk2, method=0: (G, len(G))
    try:
        lx = case.period[0]
        ly = case.period[1] if case.is_2d else 1.0
        obj = grcwa.obj(len(G), [lx, 0.0], [0.0, ly], 1.0 / case.wavelength_um, case.theta_rad,
                        case.phi_rad, verbose=0)
        obj.Add_LayerUniform(0.0, case.n_sup ** 2)
        patterned = []
        for li, lay in enumerate(case.layers):
            if lay.shapes:
                ny_cells, nx_cells = raster.shape[1], raster.shape[2]
                obj.Add_LayerGrid(lay.thickness, nx_cells, ny_cells)
                patterned.append((raster[li] ** 2).T.ravel())  # grcwa grids are [ix, iy]
            else:
                obj.Add_LayerUniform(lay.thickness, lay.background ** 2)
        obj.Add_LayerUniform(0.0, case.n_sub ** 2)
        obj.Init_Setup(Gmethod=0)
        if patterned:
            obj.GridLayer_geteps(np.concatenate(patterned))
    finally:
        grcwa_rcwa.Lattice_getG = original
    out = {}
    for pol in pols:
        p_amp, s_amp = (0.0, 1.0) if pol == "s" else (1.0, 0.0)
        # ``order`` is the position of the incident (0, 0) order in G: the centre of our list
        obj.MakeExcitationPlanewave(p_amp, 0.0, s_amp, 0.0, order=len(G) // 2)
        R, T = obj.RT_Solve(normalize=1, byorder=1)
        out["R_" + pol] = np.real(R).reshape(2 * hy + 1, 2 * hx + 1)
        out["T_" + pol] = np.real(T).reshape(2 * hy + 1, 2 * hx + 1)
    return out


GRCWA_FORMULATION = {
    1: "S4-style S-matrix, Laurent rule (no Li inverse rule), eps from the DFT of a fine grid",
    2: "S4-style S-matrix, Laurent rule (no Li rules), eps from the DFT of a fine grid",
}


# --------------------------------------------------------------------------------------------
# fmmax
# --------------------------------------------------------------------------------------------


def fmmax_version() -> str:
    import fmmax

    return str(fmmax.__version__)


_FMMAX_JIT: dict = {}


def _fmmax_solver(case: Case, shapes: tuple, pols: tuple[str, ...]):
    """The jit-compiled fmmax solve of ``case`` for ``pols`` (built once per shape set)."""
    import jax
    import jax.numpy as jnp
    from fmmax import basis, fields, fmm, scattering

    key = (id(case), shapes, pols)
    if key in _FMMAX_JIT:
        return _FMMAX_JIT[key]
    hx, hy = case.half_orders
    mm, nn = np.meshgrid(np.arange(-hx, hx + 1), np.arange(-hy, hy + 1))  # [n + hy, m + hx]
    expansion = basis.Expansion(basis_coefficients=np.stack([-mm.ravel(), -nn.ravel()], axis=1))  # G = -(ours)
    ly = case.period[1] if case.is_2d else 1.0
    lattice = basis.LatticeVectors(u=jnp.array([case.period[0], 0.0]), v=jnp.array([0.0, ly]))
    n_terms = mm.size
    zero = n_terms // 2
    thick = [0.0] + [lay.thickness for lay in case.layers] + [0.0]
    c, s_ = math.cos(case.phi_rad), math.sin(case.phi_rad)
    # fmmax's amplitudes are of the tangential H of its uniform-layer plane waves (x then y
    # components): s incidence has H along k_t (cos phi, sin phi), p along s-hat.
    inc = np.zeros((2 * n_terms, len(pols)), dtype=complex)
    for j, pol in enumerate(pols):
        hxy = (c, s_) if pol == "s" else (-s_, c)
        inc[zero, j], inc[zero + n_terms, j] = hxy

    def solve(perms):
        wl = jnp.asarray(case.wavelength_um)
        k_in = basis.plane_wave_in_plane_wavevector(wl, jnp.asarray(case.theta_rad), jnp.asarray(case.phi_rad),
                                                    perms[0][0, 0])
        layers = [fmm.eigensolve_isotropic_media(wl, k_in, lattice, p, expansion, formulation=fmm.Formulation.FFT)
                  for p in perms]
        sm = scattering.stack_s_matrix(layers, thick)
        a = jnp.asarray(inc)
        nil = jnp.zeros_like(a)
        flux_in, _ = fields.amplitude_poynting_flux(a, nil, layers[0])
        _, flux_r = fields.amplitude_poynting_flux(nil, sm.s21 @ a, layers[0])
        flux_t, _ = fields.amplitude_poynting_flux(sm.s11 @ a, nil, layers[-1])
        power = jnp.sum(flux_in, axis=0)
        R = -(flux_r[:n_terms] + flux_r[n_terms:]) / power
        T = (flux_t[:n_terms] + flux_t[n_terms:]) / power
        return R, T

    _FMMAX_JIT[key] = jax.jit(solve)
    return _FMMAX_JIT[key]


def solve_fmmax(case: Case, raster: np.ndarray, pols: tuple[str, ...] = ("s", "p")) -> dict[str, np.ndarray]:
    """The polarizations ``pols`` with fmmax (JAX, CPU, float64); arrays indexed [n + hy, m + hx].

    fmmax (1.7) conventions, checked against ours by bench_solve's max|dDE|:

    * exp(-i omega t) (eps = (n + ik)^2); lengths in micrometres, wavelength too;
    * its layers are stacked along its +z from the incidence side (a mirror of ours, as
      grcwa's, which leaves efficiencies of isotropic media unchanged); the tangential
      wave vector of the incident wave is k0 n_sup (sin t cos p, sin t sin p), as ours;
    * its expansion coefficient G has k_x = k_x,inc + G_1 2 pi / Lambda_x: G = -(m, n);
      the expansion is set to the full rectangle |m| <= hx, |n| <= hy;
    * a 1D grating is a 2D cell one raster row high with only n = 0 in the expansion.

    Formulation: ``Formulation.FFT`` (Laurent's rule on the FFT of the raster: the cheapest
    of fmmax's; its vector formulations converge faster in p but cost an extra tangent-field
    computation). Efficiencies from the modal Poynting fluxes (``amplitude_poynting_flux``)
    of the scattering matrix's s11 and s21.
    """
    import jax

    jax.config.update("jax_enable_x64", True)
    perms = [np.full((1, 1), case.n_sup ** 2, dtype=complex)]
    for li, lay in enumerate(case.layers):
        perms.append((raster[li] ** 2).T.astype(complex) if lay.shapes else np.full((1, 1), lay.background ** 2 + 0j))
    perms.append(np.full((1, 1), case.n_sub ** 2, dtype=complex))
    solve = _fmmax_solver(case, tuple(p.shape for p in perms), pols)
    R, T = (np.asarray(x) for x in solve(perms))
    hx, hy = case.half_orders
    out = {}
    for j, pol in enumerate(pols):
        out["R_" + pol] = R[:, j].reshape(2 * hy + 1, 2 * hx + 1)
        out["T_" + pol] = T[:, j].reshape(2 * hy + 1, 2 * hx + 1)
    return out


FMMAX_FORMULATION = {
    1: "S-matrix (Whittaker & Culshaw / Liu 2012), Laurent rule on the FFT of the raster (Formulation.FFT), jit",
    2: "S-matrix (Whittaker & Culshaw / Liu 2012), Laurent rule on the FFT of the raster (Formulation.FFT), jit",
}


# --------------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------------


def prepare(case: Case, peer: str) -> tuple[np.ndarray, str]:
    """The raster a peer needs and a note on how exact it is."""
    if peer == "meent":
        nx, exact_x = _axis_cells(case, 0, MAX_EXACT_CELLS_2D if case.is_2d else MAX_EXACT_CELLS_1D,
                                  MAX_EXACT_CELLS_2D if case.is_2d else MAX_EXACT_CELLS_1D)
        ny, exact_y = (_axis_cells(case, 1, MAX_EXACT_CELLS_2D, MAX_EXACT_CELLS_2D) if case.is_2d
                       else (1, True))
        note = "exact boundaries" if (exact_x and exact_y) else "boundaries rounded to a raster"
    else:
        # grcwa takes the DFT of a sampled grid: use a fine grid whose cell edges still fall
        # on every boundary when the boundaries allow it (a multiple of the exact grid).
        def fine(axis: int, target: int) -> int:
            n, exact = _axis_cells(case, axis, target, target)
            return n * max(1, -(-target // n)) if exact else target

        nx = fine(0, GRCWA_CELLS_2D if case.is_2d else GRCWA_CELLS_1D)
        ny = fine(1, GRCWA_CELLS_2D) if case.is_2d else 1
        note = f"eps sampled on a {nx}x{ny} grid (DFT coefficients)"
    return rasterize(case, nx, ny), note


SOLVERS = {"meent": (solve_meent, meent_version, MEENT_FORMULATION),
           "grcwa": (solve_grcwa, grcwa_version, GRCWA_FORMULATION),
           "fmmax": (solve_fmmax, fmmax_version, FMMAX_FORMULATION)}
FACTORIZATION = {("meent", 1): "li1996", ("meent", 2): "li1997-reversed-nesting"}


def cpu_time() -> float:
    """CPU time of this process, the measure bench_solve.py uses for ours."""
    return time.process_time()


class PeerSession:
    """One peer on one case, warmed up once (imports, caches, fmmax's jit compilation),
    then timed round by round: :meth:`round` is what ``--serve`` answers per request."""

    def __init__(self, case: Case, peer: str) -> None:
        if peer not in PEERS:
            raise CaseError(f"--peer: expected one of {PEERS}, got {peer!r}")
        self.case, self.peer = case, peer
        self.solver, self.version_of, self.formulations = SOLVERS[peer]
        self.raster, self.note = prepare(case, peer)
        # meent answers one polarization with its both-polarization solve except in 1D
        # classical mount: there the s and p calls are that same call, timed once.
        same = peer == "meent" and (case.is_2d or case.phi_rad != 0.0)
        self.timed = {"both": POL_SETS["both"]} if same else POL_SETS
        self.results = {key: self.solver(case, self.raster, pols) for key, pols in self.timed.items()}  # warm-up

    def round(self, repeats: int) -> dict:
        """``repeats`` interleaved timed calls for s, p and both, in CPU seconds, and the result."""
        times: dict[str, list[float]] = {key: [] for key in self.timed}
        for _ in range(repeats):
            for key, pols in self.timed.items():
                t0 = cpu_time()
                self.results[key] = self.solver(self.case, self.raster, pols)
                times[key].append(cpu_time() - t0)
        for key in POL_SETS:
            times.setdefault(key, times["both"])
            self.results.setdefault(key, self.results["both"])
        eff = self.results["both"]
        # The single-polarization routes agree with the two-polarization one (a check of the route).
        single_vs_both = max(float(np.max(np.abs(self.results[pol]["R_" + pol] - eff["R_" + pol]))) for pol in ("s", "p"))
        orders, totals = build_output(self.case, eff)
        kind = 2 if self.case.is_2d else 1
        return {
            "peer": self.peer,
            "version": self.version_of(),
            "case": self.case.name,
            "seconds_per_solve": statistics.median(times["both"]),
            "seconds_s": statistics.median(times["s"]),
            "seconds_p": statistics.median(times["p"]),
            "seconds_all": times["both"],
            "seconds_all_s": times["s"],
            "seconds_all_p": times["p"],
            "timer": "process_time (CPU)",
            "repeats": repeats,
            "solve_covers": "both polarizations (s and p); seconds_s / seconds_p: one",
            "single_vs_both_max_abs_dR": single_vs_both,
            "formulation": self.formulations[kind],
            "factorization": FACTORIZATION.get((self.peer, kind), "laurent"),
            "raster": self.note,
            "orders": orders,
            "totals": totals,
            "numpy": np.__version__,
            "threads": 1,
        }


def run(case: Case, peer: str, repeats: int) -> dict:
    """``repeats`` timed rounds after a warm-up; 0: one two-polarization solve, untimed (a reference)."""
    if repeats == 0:
        solver, version_of, formulations = SOLVERS[peer]
        raster, note = prepare(case, peer)
        orders, totals = build_output(case, solver(case, raster, ("s", "p")))
        return {"peer": peer, "version": version_of(), "case": case.name, "orders": orders, "totals": totals,
                "raster": note, "formulation": formulations[2 if case.is_2d else 1]}
    return PeerSession(case, peer).round(repeats)


def serve(case: Case, peer: str) -> int:
    """--serve: warm up once, print a line ``ready``, then answer each stdin line (the number
    of repeats) with one JSON line of :meth:`PeerSession.round`, until stdin closes; so the
    caller can interleave rounds with its own timings without paying the warm-up again."""
    session = PeerSession(case, peer)
    print("ready", flush=True)
    for line in sys.stdin:
        if not line.strip():
            continue
        json.dump(session.round(int(line)), sys.stdout)
        sys.stdout.write("\n")
        sys.stdout.flush()
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("case", help="path of a case JSON file")
    ap.add_argument("--peer", default=None, help=f"one of {PEERS} (default: the case's 'peer' or meent)")
    ap.add_argument("--repeats", type=int, default=None, help="timed repeats after one warm-up (default 5; 0: one untimed solve)")
    ap.add_argument("--serve", action="store_true",
                    help="warm up once, then time one round per stdin line (its repeats), one JSON line each")
    args = ap.parse_args(argv)
    try:
        with open(args.case, encoding="utf-8") as fh:
            data = json.load(fh)
        case = parse_case(data)
        peer = args.peer or data.get("peer", "meent")
        repeats = args.repeats if args.repeats is not None else int(data.get("repeats", 5))
        if repeats < 0:
            raise CaseError(f"--repeats: expected >= 0 (0: one untimed solve), got {repeats}")
        if args.serve:
            return serve(case, peer)
        result = run(case, peer, repeats)
    except (OSError, json.JSONDecodeError, CaseError) as exc:
        print(f"peer_runner: {args.case}: {exc}", file=sys.stderr)
        return 2
    json.dump(result, sys.stdout)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

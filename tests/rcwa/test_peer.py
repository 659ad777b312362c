"""Cross-check against an independent code: grcwa (Jin et al. 2020, ACS Photonics 7, 2350).

grcwa is an S-matrix RCWA in the style of S4 (Liu & Fan 2012) written in numpy. It has
Laurent's rule only: in-plane permittivity [[eps]] for both components and [[eps]]^-1 for
1/eps_z, which is our ``factorization="laurent"``. Everything else -- its eigen-solves,
its S-matrix stack, its Poynting-flux efficiencies, its polarization and order
conventions -- is its own, so agreement tests our whole chain after the layer matrices.

Conventions of grcwa 0.1.2 (read from its source, and the same mapping that
benchmarks/peer_runner.py uses for the timings; this test imports nothing from there):

* exp(-i omega t) like ours, so lossy media have Im(n) > 0 in both; c = 1, frequency
  1 / lambda (lengths in um);
* its layers are stacked along its +z from the incidence side: its z is our -z, a mirror
  of the whole problem that leaves x, y, theta, phi and efficiencies of isotropic media
  unchanged;
* its reciprocal-lattice index G gives k_x = k_x,inc + 2 pi G_1 / Lx: G = -(m, n);
* ``MakeExcitationPlanewave(p_amp, p_phase, s_amp, s_phase)``: s_amp = 1 is s incidence;
* its own truncation is circular; the adapter hands it our rectangle |m| <= Nx/2,
  |n| <= Ny/2 (by replacing its lattice selection for the duration of the set-up).

Two comparisons:

1. The same truncated problem: grcwa's public interface takes the permittivity only on a
   sampled grid (Fourier coefficients by DFT), so the adapter gives grcwa's own
   eigen-solver the exact convolution matrix instead (closed-form coefficients of the
   rectangles, written here independently of rcwa.fourier) -- what its
   ``GridLayer_geteps`` does with the DFT one. Same harmonics, same rule, same
   coefficients: the two codes solve the same equations, so TOLERANCE_SAME_PROBLEM = 1e-10
   leaves round-off only (measured <= 1e-14 for 1D at 21-41 and 2D at 5x5-9x9 harmonics).
2. grcwa as a user runs it, on its sampled grid: on a grid whose cell edges fall on every
   boundary, its DFT coefficient of order g is the exact one times
   (pi g / N) / sin(pi g / N) and a phase (a half-cell shift, which moves no
   efficiency): relative errors up to (pi g_max / N)^2 / 6 = 1.1e-4 for the highest
   coefficient (g_max = 8, N = 1000), mostly in orders that carry little power.
   Measured: 2.5e-7 on efficiencies; TOLERANCE_SAMPLED = 1e-5.

Each comparison also checks that the wrong mappings (m -> -m, n -> -n, s <-> p) would
fail by far more than the tolerance, so a lucky symmetry cannot pass the test.

grcwa is pinned in the test extras (pyproject.toml): the adapter replaces its lattice
selection and sets its per-layer eigen-solutions, internals that a new release may move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

import rcwa
from tests.rcwa.helpers import nk, structure

grcwa = pytest.importorskip("grcwa", reason="grcwa (the peer RCWA code) is not installed: pip install -e '.[test]'")
grcwa_rcwa = pytest.importorskip("grcwa.rcwa")

TOLERANCE_SAME_PROBLEM = 1e-10
TOLERANCE_SAMPLED = 1e-5
MAPPING_CONTRAST = 100  # a wrong mapping must miss by at least this many tolerances
GRID_CELLS = 1000


@dataclass(frozen=True)
class Box:
    """A rectangle x0 <= x < x1, y0 <= y < y1 of index n (a stripe spans all of y)."""

    x0: float
    x1: float
    y0: float
    y1: float
    n: complex


@dataclass(frozen=True)
class PeerLayer:
    thickness: float
    n_background: complex
    boxes: tuple[Box, ...] = ()


def exact_coefficients(lx: float, ly: float, layer: PeerLayer, gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """c(gx, gy) = (1 / (Lx Ly)) int eps(x, y) exp(-2 pi i (gx x / Lx + gy y / Ly)) dx dy
    of a background with boxes painted on it (non-overlapping)."""

    def interval(g: np.ndarray, a: float, b: float, length: float) -> np.ndarray:
        safe = np.where(g == 0, 1, g)
        ft = (np.exp(-2j * np.pi * safe * b / length) - np.exp(-2j * np.pi * safe * a / length)) / (-2j * np.pi * safe)
        return np.where(g == 0, (b - a) / length, ft)

    GX, GY = np.meshgrid(gx, gy, indexing="ij")
    eps_bg = layer.n_background**2
    c = np.where((GX == 0) & (GY == 0), eps_bg, 0.0).astype(complex)
    for box in layer.boxes:
        c += (box.n**2 - eps_bg) * interval(GX, box.x0, box.x1, lx) * interval(GY, box.y0, box.y1, ly)
    return c


def sampled_permittivity(lx: float, ly: float, layer: PeerLayer) -> np.ndarray:
    """eps on a GRID_CELLS x GRID_CELLS grid of cell centres, indexed [ix, iy] as grcwa wants."""
    centres = (np.arange(GRID_CELLS) + 0.5) / GRID_CELLS
    X, Y = np.meshgrid(centres * lx, centres * ly, indexing="ij")
    eps = np.full(X.shape, layer.n_background**2, dtype=complex)
    for box in layer.boxes:
        eps[(X >= box.x0) & (X < box.x1) & (Y >= box.y0) & (Y < box.y1)] = box.n**2
    return eps.ravel()


def grcwa_efficiencies(monkeypatch, *, wavelength_nm: float, theta_deg: float, phi_deg: float, period: tuple[float, float],
                       orders: tuple[int, int], n_sup: complex, n_sub: complex, layers: list[PeerLayer],
                       exact: bool) -> dict[str, np.ndarray]:
    """R and T per order for s and p incidence, arrays indexed [m + Nx // 2, n + Ny // 2] (our m, n)."""
    (lx, ly), (nx, ny) = period, orders
    M, N = np.meshgrid(np.arange(nx) - nx // 2, np.arange(ny) - ny // 2, indexing="ij")
    G = np.stack([-M.ravel(), -N.ravel()], axis=1)  # grcwa's index is minus ours
    with monkeypatch.context() as patch:
        patch.setattr(grcwa_rcwa, "Lattice_getG", lambda nG, Lk1, Lk2, method=0: (G, len(G)))
        solver = grcwa.obj(len(G), [lx, 0.0], [0.0, ly], 1000.0 / wavelength_nm, math.radians(theta_deg),
                           math.radians(phi_deg), verbose=0)
        solver.Add_LayerUniform(0.0, n_sup**2)
        for layer in layers:
            if layer.boxes:
                solver.Add_LayerGrid(layer.thickness, GRID_CELLS, GRID_CELLS)
            else:
                solver.Add_LayerUniform(layer.thickness, layer.n_background**2)
        solver.Add_LayerUniform(0.0, n_sub**2)
        solver.Init_Setup(Gmethod=0)
    patterned = [(i + 1, layer) for i, layer in enumerate(layers) if layer.boxes]  # position 0 is the superstrate
    if exact:
        for position, layer in patterned:
            _set_exact_layer(solver, position, exact_coefficients(lx, ly, layer, np.arange(1 - nx, nx), np.arange(1 - ny, ny)), G)
    else:
        solver.GridLayer_geteps(np.concatenate([sampled_permittivity(lx, ly, layer) for _, layer in patterned]))
    out = {}
    for pol, (p_amp, s_amp) in (("s", (0.0, 1.0)), ("p", (1.0, 0.0))):
        solver.MakeExcitationPlanewave(p_amp, 0.0, s_amp, 0.0, order=len(G) // 2)  # (0, 0) is the middle of G
        R, T = solver.RT_Solve(normalize=1, byorder=1)
        out[f"R_{pol}"], out[f"T_{pol}"] = np.real(R).reshape(nx, ny), np.real(T).reshape(nx, ny)
    return out


def _set_exact_layer(solver, position: int, c: np.ndarray, G: np.ndarray) -> None:
    """Give grcwa's eigen-solver the exact Laurent matrices of one layer, as its
    GridLayer_geteps does with DFT ones. c is indexed [gx + Nx - 1, gy + Ny - 1]."""
    gx0, gy0 = (c.shape[0] - 1) // 2, (c.shape[1] - 1) // 2
    d = G[:, None, :] - G[None, :, :]  # grcwa's convolution matrix: c(G_i - G_j)
    E = c[d[..., 0] + gx0, d[..., 1] + gy0]
    kp = grcwa_rcwa.MakeKPMatrix(solver.omega, 1, np.linalg.inv(E), solver.kx, solver.ky)
    in_plane = np.block([[E, np.zeros_like(E)], [np.zeros_like(E), E]])  # Laurent for both components
    q, modes = grcwa_rcwa.SolveLayerEigensystem(solver.omega, solver.kx, solver.ky, kp, in_plane)
    solver.kp_list[position], solver.q_list[position], solver.phi_list[position] = kp, q, modes


def differences(ours, theirs: dict[str, np.ndarray], flip_m=False, flip_n=False, swap_pol=False) -> float:
    """Largest |difference| over every order's R and T, s and p, and the totals."""
    m, n = ours.all_orders["m"], ours.all_orders["n"]
    nx, ny = theirs["R_s"].shape
    i, j = (-m if flip_m else m) + nx // 2, (-n if flip_n else n) + ny // 2
    worst = 0.0
    for column, pol in enumerate("ps" if swap_pol else "sp"):
        for side in ("R", "T"):
            mine, peer = ours.all_orders[side][:, column], theirs[f"{side}_{pol}"][i, j]
            worst = max(worst, float(np.max(np.abs(mine - peer))), abs(float(mine.sum() - peer.sum())))
    return worst


def assert_agree(ours, theirs, tolerance: float, two_d: bool) -> None:
    assert differences(ours, theirs) < tolerance
    wrong = [differences(ours, theirs, flip_m=True), differences(ours, theirs, swap_pol=True)]
    if two_d:
        wrong.append(differences(ours, theirs, flip_n=True))
    assert min(wrong) > MAPPING_CONTRAST * tolerance, wrong


# A lossy, asymmetric lamellar grating (the ridge is absorbing: Im(n) > 0 in both codes).
LAMELLAR_PERIOD = 1.0
LAMELLAR_RIDGE = Box(0.1, 0.45, 0.0, 1.0, complex(2.0, 0.1))
LAMELLAR_DEPTH = 0.5


@pytest.mark.parametrize("theta, phi", [(20.0, 0.0), (30.0, 40.0)], ids=["classical", "conical"])
def test_lamellar_grating_matches_grcwa(monkeypatch, theta, phi):
    ridge = LAMELLAR_RIDGE
    ours = rcwa.solve(structure([LAMELLAR_PERIOD], nk(1.0), nk(1.5), [{"thickness": LAMELLAR_DEPTH, "material": nk(1.0),
                      "shapes": [{"material": nk(ridge.n.real, ridge.n.imag), "x": [ridge.x0, ridge.x1]}]}]),
                      600.0, theta, phi, 21, "s", "laurent")
    theirs = grcwa_efficiencies(monkeypatch, wavelength_nm=600.0, theta_deg=theta, phi_deg=phi, period=(LAMELLAR_PERIOD, 1.0),
                                orders=(21, 1), n_sup=1.0, n_sub=1.5, layers=[PeerLayer(LAMELLAR_DEPTH, 1.0, (ridge,))],
                                exact=True)
    assert len(ours.orders) >= 3  # several propagating orders: the order mapping is tested
    assert_agree(ours, theirs, TOLERANCE_SAME_PROBLEM, two_d=False)


# An L-shaped lossy cell (mirror-symmetric in neither x nor y) over a uniform film, in
# conical incidence: every mapping of orders, polarizations and layers is exercised.
L_PERIOD = (1.0, 0.8)
L_BOXES = (Box(0.1, 0.5, 0.1, 0.3, complex(1.6, 0.05)), Box(0.1, 0.3, 0.3, 0.6, complex(1.6, 0.05)))
L_LAYERS = [PeerLayer(0.4, 1.0, L_BOXES), PeerLayer(0.1, 2.0)]


def _l_cell_ours(orders: int):
    shapes = [{"material": nk(b.n.real, b.n.imag), "rect": {"center": [(b.x0 + b.x1) / 2, (b.y0 + b.y1) / 2],
               "size": [b.x1 - b.x0, b.y1 - b.y0]}} for b in L_BOXES]
    s = structure(L_PERIOD, nk(1.0), nk(1.5), [{"thickness": 0.4, "material": nk(1.0), "shapes": shapes},
                                               {"thickness": 0.1, "material": nk(2.0)}])
    return rcwa.solve(s, 550.0, 35.0, 25.0, (orders, orders), "s", "laurent")


def test_l_shaped_2d_cell_matches_grcwa(monkeypatch):
    theirs = grcwa_efficiencies(monkeypatch, wavelength_nm=550.0, theta_deg=35.0, phi_deg=25.0, period=L_PERIOD,
                                orders=(7, 7), n_sup=1.0, n_sub=1.5, layers=L_LAYERS, exact=True)
    assert_agree(_l_cell_ours(7), theirs, TOLERANCE_SAME_PROBLEM, two_d=True)


def test_l_shaped_2d_cell_matches_grcwa_on_its_own_grid(monkeypatch):
    theirs = grcwa_efficiencies(monkeypatch, wavelength_nm=550.0, theta_deg=35.0, phi_deg=25.0, period=L_PERIOD,
                                orders=(5, 5), n_sup=1.0, n_sub=1.5, layers=L_LAYERS, exact=False)
    assert_agree(_l_cell_ours(5), theirs, TOLERANCE_SAMPLED, two_d=True)

"""Fourier factorization rules (rcwa/factorization.py): which rule is chosen, and the
matrices each rule builds, against independent constructions written here.

* 1D (Li 1996, JOSA A 13, 1870, Eq. 37): ``Exx = [[1/eps]]^-1`` (inverse rule),
  ``Eyy = [[eps]]`` (Laurent); the Laurent rule uses ``[[eps]]`` for both. ``[[f]]`` is
  the Toeplitz matrix ``C[m, n] = c(n - m)`` of f's Fourier coefficients (our order sign).
* 2D (Li 1997, JOSA A 14, 2758, Eqs. 38-39): ``Exx`` is the inverse rule along x inside
  each y-slab, combined across slabs by the Laurent rule along y; ``Eyy`` the reverse.
* Normal vector method (Schuster et al. 2007): Hermitian for lossless cells (its
  symmetrized product), so the truncated problem conserves energy exactly.
* With one retained harmonic the rules are zeroth-order effective-medium theory (Rytov
  1956): the lamellar layer is a uniaxial film, eps along the stripes (y, z) the mean
  <eps>, across them (x) <eps> with Laurent and the harmonic mean 1 / <1/eps> with Li.

Tolerances: TOLERANCE_MATRIX = 1e-12 (the same integrals in closed form, one small matrix
inverse: round-off); TOLERANCE_HERMITIAN = 1e-12 relative (the symmetrized product is
Hermitian in exact arithmetic); TOLERANCE_FILM = 1e-12 (the solver and the film formula
are both exact for a single harmonic).
"""

from __future__ import annotations

import numpy as np
import pytest

import rcwa
from rcwa.factorization import FACTORIZATION_RULES, HarmonicIndices, permittivity_matrices, resolve_rule
from tests.rcwa.helpers import nk, structure
from workbench.core.errors import UserInputError

TOLERANCE_MATRIX = 1e-12
TOLERANCE_HERMITIAN = 1e-12
TOLERANCE_FILM = 1e-12
WAVELENGTH_NM = 600.0


def _cell(period, shapes, background: float = 1.0):
    return structure(period, nk(1.0), nk(1.5), [{"thickness": 0.3, "material": nk(background), "shapes": shapes}])


def _eps_of(material) -> complex:
    return complex(material.epsilon(WAVELENGTH_NM))


def _matrices(s, rule: str, harmonics: HarmonicIndices):
    return permittivity_matrices(s.layers[0], s.period, _eps_of, harmonics, rule)


def _harmonics_1d(n: int) -> HarmonicIndices:
    m = np.arange(n) - n // 2
    return HarmonicIndices(m, np.zeros_like(m))


def _harmonics_2d(nx: int, ny: int) -> HarmonicIndices:
    M, N = np.meshgrid(np.arange(nx) - nx // 2, np.arange(ny) - ny // 2, indexing="ij")
    return HarmonicIndices(M.ravel(), N.ravel())


def interval_coefficient(g: np.ndarray, a: float, b: float, period: float) -> np.ndarray:
    """(1 / period) int_a^b exp(-2 pi i g x / period) dx."""
    safe = np.where(g == 0, 1, g)
    value = (np.exp(-2j * np.pi * safe * b / period) - np.exp(-2j * np.pi * safe * a / period)) / (-2j * np.pi * safe)
    return np.where(g == 0, (b - a) / period, value)


def toeplitz_of_profile(pieces, background: complex, period: float, m: np.ndarray) -> np.ndarray:
    """C[i, j] = c(m_j - m_i) of a background with non-overlapping pieces (a, b, value)."""
    d = m[None, :] - m[:, None]
    c = np.where(d == 0, background, 0.0).astype(complex)
    for a, b, value in pieces:
        c = c + (value - background) * interval_coefficient(d, a, b, period)
    return c


# ---------------------------------------------------------------- rule selection


@pytest.mark.parametrize("shapes, period, expected", [
    ([{"material": nk(2.0), "x": [0.1, 0.4]}], [1.0], "li"),
    ([{"material": nk(2.0), "rect": {"center": [0.5, 0.5], "size": [0.4, 0.3]}}], [1.0, 1.0], "li"),
    ([{"material": nk(2.0), "circle": {"center": [0.5, 0.5], "radius": 0.3}}], [1.0, 1.0], "nv"),
    ([{"material": nk(2.0), "rect": {"center": [0.3, 0.3], "size": [0.2, 0.2]}},
      {"material": nk(2.0), "polygon": [[0.5, 0.5], [0.9, 0.5], [0.6, 0.9]]}], [1.0, 1.0], "nv"),
], ids=["1D stripes", "2D rectangles", "2D circle", "2D rectangle and polygon"])
def test_auto_picks_li_where_it_is_exact_and_nv_elsewhere(shapes, period, expected):
    s = _cell(period, shapes)
    assert resolve_rule("auto", s.dimension, s.layers) == expected
    orders = 3 if s.dimension == 1 else (3, 3)
    assert rcwa.solve(s, WAVELENGTH_NM, 10.0, 20.0, orders, "s").factorization == expected


@pytest.mark.parametrize("rule", [r for r in FACTORIZATION_RULES if r != "auto"])
def test_an_explicit_rule_is_kept(rule):
    assert resolve_rule(rule, 2, rcwa.load_structure("gold2d").layers) == rule


@pytest.mark.parametrize("rule", ["Li", "inverse", ""])
def test_unknown_rule_is_a_user_error(rule):
    with pytest.raises(UserInputError) as info:
        resolve_rule(rule, 1)
    assert info.value.field == "factorization" and all(r in info.value.expected for r in FACTORIZATION_RULES)


# ---------------------------------------------------------------- 1D matrices

# A lossy two-stripe layer; the second stripe wraps across the cell edge.
STRIPES_1D = [{"material": nk(0.3, 3.0), "x": [0.1, 0.35]}, {"material": nk(2.0, 0.1), "x": [0.8, 1.05]}]
PIECES_1D = [(0.1, 0.35, complex(0.3, 3.0)), (0.8, 1.0, complex(2.0, 0.1)), (0.0, 0.05, complex(2.0, 0.1))]


def test_1d_matrices_of_each_rule():
    s, h = _cell([1.0], STRIPES_1D), _harmonics_1d(15)
    eps = [(a, b, v**2) for a, b, v in PIECES_1D]
    laurent = toeplitz_of_profile(eps, 1.0, 1.0, h.m)
    inverse = np.linalg.inv(toeplitz_of_profile([(a, b, 1 / v) for a, b, v in eps], 1.0, 1.0, h.m))
    expected = {"laurent": (laurent, laurent), "li": (inverse, laurent), "nv": (inverse, laurent)}  # nv is li in 1D
    for rule, (exx, eyy) in expected.items():
        pm = _matrices(s, rule, h)
        for name, got, want in (("E", pm.E, laurent), ("exx", pm.exx, exx), ("eyy", pm.eyy, eyy)):
            assert np.abs(got - want).max() < TOLERANCE_MATRIX * np.abs(want).max(), (rule, name)


def test_1d_lossless_matrices_are_hermitian_with_spectra_inside_the_profile():
    """A Toeplitz matrix of a real profile is Hermitian with eigenvalues between the
    profile's extremes (Grenander & Szego 1958, Sec. 5.2); so is the inverse of the
    Toeplitz matrix of 1/eps (its eigenvalues between 1/max and 1/min, inverted)."""
    s = _cell([1.0], [{"material": nk(1.5), "x": [0.1, 0.4]}, {"material": nk(3.0), "x": [0.6, 0.7]}])
    pm = _matrices(s, "li", _harmonics_1d(41))
    for matrix in (pm.E, pm.exx):
        assert np.abs(matrix - matrix.conj().T).max() < TOLERANCE_HERMITIAN * np.abs(matrix).max()
        values = np.linalg.eigvalsh(matrix)
        assert values.min() > 1.0 - TOLERANCE_MATRIX and values.max() < 9.0 + TOLERANCE_MATRIX


# ---------------------------------------------------------------- 2D matrices


def li_1997_exx(lx, ly, eps_bg, box, h: HarmonicIndices, axis: int) -> np.ndarray:
    """Li 1997, Eqs. 38-39, for one rectangle box = (x0, x1, y0, y1, eps): slabs across
    ``axis`` (two kinds: through the box and beside it), the inverse rule along ``axis``
    inside each, the Laurent rule (a slab's share of each Fourier coefficient) across."""
    x0, x1, y0, y1, eps = box
    along, across = (lx, ly) if axis == 0 else (ly, lx)
    (a0, a1), (b0, b1) = ((x0, x1), (y0, y1)) if axis == 0 else ((y0, y1), (x0, x1))
    i_along, i_across = (h.m, h.n) if axis == 0 else (h.n, h.m)
    distinct = np.unique(i_along)  # the inverse rule acts on one row of harmonics
    position = np.searchsorted(distinct, i_along)
    slab_inverse = np.linalg.inv(toeplitz_of_profile([(a0, a1, 1 / eps)], 1 / eps_bg, along, distinct))
    inside = slab_inverse[position[:, None], position[None, :]]
    beside = eps_bg * (i_along[:, None] == i_along[None, :])
    d = i_across[None, :] - i_across[:, None]
    share_inside = interval_coefficient(d, b0, b1, across)
    return inside * share_inside + beside * (interval_coefficient(d, 0.0, across, across) - share_inside)


def test_2d_li_rule_is_li_1997_for_a_rectangle():
    box = (0.15, 0.6, 0.2, 0.45, complex(0.5, 2.5) ** 2)
    s = _cell([1.0, 0.8], [{"material": nk(0.5, 2.5), "rect": {"center": [0.375, 0.325], "size": [0.45, 0.25]}}],
              background=1.2)
    h = _harmonics_2d(7, 5)
    pm = _matrices(s, "li", h)
    for name, got, axis in (("exx", pm.exx, 0), ("eyy", pm.eyy, 1)):
        want = li_1997_exx(1.0, 0.8, 1.44, box, h, axis)
        assert np.abs(got - want).max() < TOLERANCE_MATRIX * np.abs(want).max(), name
    assert pm.exy is None and pm.eyx is None  # Li 1997 has no cross terms


def test_2d_li_rule_of_a_y_invariant_cell_is_the_1d_rule():
    one = _matrices(_cell([1.0], STRIPES_1D[:1]), "li", _harmonics_1d(11))
    two = _matrices(_cell([1.0, 0.7], [{"material": nk(0.3, 3.0), "rect": {"center": [0.225, 0.35], "size": [0.25, 0.7]}}]),
                    "li", _harmonics_2d(11, 1))
    for name in ("E", "exx", "eyy"):
        want = getattr(one, name)
        assert np.abs(getattr(two, name) - want).max() < TOLERANCE_MATRIX * np.abs(want).max(), name


def test_normal_vector_tensor_is_hermitian_for_a_lossless_cell():
    s = _cell([1.0, 0.9], [{"material": nk(2.0), "circle": {"center": [0.4, 0.5], "radius": 0.3}},
                           {"material": nk(1.5), "polygon": [[0.7, 0.1], [0.95, 0.2], [0.8, 0.4]]}])
    pm = _matrices(s, "nv", _harmonics_2d(5, 5))
    assert pm.exy is not None and np.array_equal(pm.exy, pm.eyx)
    for name in ("E", "exx", "eyy", "exy"):
        matrix = getattr(pm, name)
        assert np.abs(matrix - matrix.conj().T).max() < TOLERANCE_HERMITIAN * np.abs(matrix).max(), name
    # The cross term is real physics here, not zero: the circle's normals turn through x and y.
    assert np.abs(pm.exy).max() > 1e-3


# ---------------------------------------------------------------- one harmonic


def uniaxial_film_reflectance(n_sup, n_sub, eps_x, eps_y, eps_z, thickness_um, theta_deg, pol) -> float:
    """R of a uniaxial film (axes x, y, z) between isotropic media, plane of incidence xz
    (Yeh 1988, Optical Waves in Layered Media, Ch. 9): s waves (E along y) see eps_y,
    kz^2 = eps_y - kx^2, admittance kz; p waves see kz^2 = eps_x (1 - kx^2 / eps_z),
    admittance kz / eps_x (the half-spaces: kz / eps)."""
    kx = n_sup * np.sin(np.radians(theta_deg))
    k0 = 2 * np.pi / (WAVELENGTH_NM / 1000.0)

    def root(z):
        r = np.sqrt(complex(z))
        return -r if r.imag < 0 else r

    k1, k3 = root(n_sup**2 - kx**2), root(n_sub**2 - kx**2)
    if pol == "s":
        k2 = root(eps_y - kx**2)
        y1, y2, y3 = k1, k2, k3
    else:
        k2 = root(eps_x * (1 - kx**2 / eps_z))
        y1, y2, y3 = k1 / n_sup**2, k2 / eps_x, k3 / n_sub**2
    r12, r23 = (y1 - y2) / (y1 + y2), (y2 - y3) / (y2 + y3)
    phase = np.exp(2j * k2 * k0 * thickness_um)
    return abs((r12 + r23 * phase) / (1 + r12 * r23 * phase)) ** 2


@pytest.mark.parametrize("rule", ["laurent", "li"])
@pytest.mark.parametrize("pol", ["s", "p"])
def test_one_harmonic_is_the_effective_medium_film(rule, pol):
    fill, eps_ridge, eps_groove, depth = 0.35, 2.2**2, 1.0, 0.3
    s = structure([0.4], nk(1.0), nk(1.5), [{"thickness": depth, "material": nk(1.0),
                  "shapes": [{"material": nk(2.2), "x": [0.0, fill * 0.4]}]}])
    mean = fill * eps_ridge + (1 - fill) * eps_groove
    harmonic = 1 / (fill / eps_ridge + (1 - fill) / eps_groove)
    eps_x = harmonic if rule == "li" else mean
    result = rcwa.solve(s, WAVELENGTH_NM, 40.0, 0.0, 1, pol, rule)
    assert result.R_total == pytest.approx(uniaxial_film_reflectance(1.0, 1.5, eps_x, mean, mean, depth, 40.0, pol),
                                           abs=TOLERANCE_FILM)
    if pol == "p":  # the test can tell the two rules apart
        assert abs(uniaxial_film_reflectance(1.0, 1.5, harmonic, mean, mean, depth, 40.0, pol)
                   - uniaxial_film_reflectance(1.0, 1.5, mean, mean, mean, depth, 40.0, pol)) > 1e-3

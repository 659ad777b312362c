"""Reciprocity and mirror symmetry of gratings.

Reciprocity theorem for gratings (Petit, Electromagnetic Theory of Gratings, Springer
1980, Ch. 1, Sec. 1.4.3): the efficiency of order m for incidence with tangential wave
vector k_i equals the efficiency of the same order m for incidence along the reversed
diffracted wave, -k_m (k_m = k_i - m G), which sends order m back along -k_i. It holds
for lossy media too. In classical mount s and p do not mix and it holds per
polarization; in conical mount for unpolarized light (the sum over input and output
polarizations of |S_ij|^2 is invariant under the transpose).

Tolerance: the reversed incidence retains a different set of harmonics (shifted by m),
so the two truncated problems differ and reciprocity holds to the truncation error, not
to round-off. For this lossy dielectric grating at 81 harmonics that difference measures
<= 2e-7 (conical, and order -1 in TM); TOLERANCE_RECIPROCITY = 1e-6 leaves a factor 5. (A metallic grating in TM
converges far more slowly: 8e-5 at 161 harmonics; see test_convergence.py.)
"""

import math

import pytest

import rcwa
from tests.rcwa.helpers import nk, structure

TOLERANCE_RECIPROCITY = 1e-6
TOLERANCE_MIRROR = 1e-10  # mirror symmetry maps the harmonic set onto itself: round-off only
HARMONICS = 81

# An asymmetric (two-stripe) lossy lamellar grating, so that reciprocity is not just symmetry.
ASYMMETRIC = structure(
    [1.2], nk(1.0), nk(1.5, 0.05),
    [{"thickness": 0.35, "material": nk(1.0), "shapes": [
        {"material": nk(2.2, 0.1), "x": [0.0, 0.3]}, {"material": nk(1.6, 0.01), "x": [0.5, 0.6]}]}],
)


def _reverse(result_kx: float, result_ky: float) -> tuple[float, float]:
    """(theta, phi) of incidence with tangential wave vector (-kx, -ky) in a unit-index superstrate."""
    kx, ky = -result_kx, -result_ky
    return math.degrees(math.asin(math.hypot(kx, ky))), math.degrees(math.atan2(ky, kx))


@pytest.mark.parametrize("pol", ["s", "p"])
@pytest.mark.parametrize("m", [1, -1, 2])
def test_reciprocity_classical_mount(pol, m):
    wl, theta = 633.0, 12.0
    a = rcwa.solve(ASYMMETRIC, wl, theta, 0.0, HARMONICS, pol)
    kx_m = math.sin(math.radians(theta)) - m * wl / 1000 / 1.2
    theta_b, phi_b = _reverse(kx_m, 0.0)
    b = rcwa.solve(ASYMMETRIC, wl, theta_b, phi_b, HARMONICS, pol)
    assert a.order(m).R == pytest.approx(b.order(m).R, abs=TOLERANCE_RECIPROCITY)
    assert a.order(m).R > 1e-4  # a real test: the order carries power


def test_reciprocity_conical_unpolarized():
    wl, theta, phi, m = 550.0, 25.0, 40.0, 1
    a = rcwa.solve(ASYMMETRIC, wl, theta, phi, HARMONICS, "unpolarized")
    kx = math.sin(math.radians(theta)) * math.cos(math.radians(phi)) - m * wl / 1000 / 1.2
    ky = math.sin(math.radians(theta)) * math.sin(math.radians(phi))
    b = rcwa.solve(ASYMMETRIC, wl, *_reverse(kx, ky), HARMONICS, "unpolarized")
    assert a.order(m).R == pytest.approx(b.order(m).R, abs=TOLERANCE_RECIPROCITY)


def test_mirror_symmetry_swaps_order_sign():
    """Mirroring the cell (x -> -x) and the incidence (phi -> 180 - phi) maps order m to -m."""
    mirrored = structure(
        [1.2], nk(1.0), nk(1.5, 0.05),
        [{"thickness": 0.35, "material": nk(1.0), "shapes": [
            {"material": nk(2.2, 0.1), "x": [0.9, 1.2]}, {"material": nk(1.6, 0.01), "x": [0.6, 0.7]}]}],
    )
    a = rcwa.solve(ASYMMETRIC, 600.0, 20.0, 30.0, 41, "unpolarized")
    b = rcwa.solve(mirrored, 600.0, 20.0, 150.0, 41, "unpolarized")
    for o in a.orders:
        assert o.R == pytest.approx(b.order(-o.m).R, abs=TOLERANCE_MIRROR)

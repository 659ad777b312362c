"""A one-layer stack solved directly gives the ETM's answer.

With one patterned layer between the half-spaces (a 2D layer, or a 1D one off the
classical mount) a single solve takes the layer's boundary conditions as one 4N x 4N
system (rcwa/cpp/stack.cpp, solve_direct; two 2N x 2N halves where the substrate is the
superstrate's medium: tests/rcwa/test_direct_symmetric.py; in classical mount one 2N x 2N
system per polarization: polarized.cpp) instead of the enhanced transmittance step's
W^-1 and V^-1 (a lamellar layer's inverse blocks are then not computed). In exact
arithmetic it is the same solution, so the two agree to round-off: 1e-12 (issue 17's
bound; measured <= 4e-15 on the 2D cases, 1.7e-13 on the lossy 1D one, whose fast path
also takes its eigenvectors by inverse iteration), on every complex amplitude of every
retained harmonic and on the efficiencies, for s, p and unpolarized light, also at
Rayleigh points of the superstrate and of the substrate (kz = 0 there: the substrate's
rows and t stay exact), over an absorbing substrate, and at normal incidence. Stacks of
more than one layer keep the ETM, and so do sweeps of 1D layers.
"""

import math

import numpy as np
import pytest

import rcwa
from rcwa import _core
from rcwa.solver import INCIDENCE_OF, prepare, s_direction
from rcwa.solver import STACK_METHODS as STACK_METHOD_OF
from tests.rcwa.helpers import nk, structure
from workbench.core.conventions import incident_tangential_k

TOLERANCE_DIRECT = 1e-12  # direct vs ETM (round-off only: the same boundary conditions, solved at once)

GOLD2D = rcwa.load_structure("gold2d")
# Symmetric about no point and mirror-free: two different blocks, on glass.
TWO_BLOCKS = [
    {"thickness": 0.25, "material": nk(1.0), "shapes": [
        {"material": nk(2.2, 0.05), "rect": {"center": [0.3, 0.3], "size": [0.4, 0.2]}},
        {"material": nk(1.8), "rect": {"center": [0.7, 0.6], "size": [0.2, 0.3]}}]}]
ASYMMETRIC = structure([1.0, 0.8], nk(1.0), nk(1.5), TWO_BLOCKS)
# A circle (normal-vector rule: Exy, Eyx nonzero) over gold.
CIRCLE_ON_GOLD = structure([0.9, 0.9], nk(1.0), "gold", [
    {"thickness": 0.1, "material": nk(1.0), "shapes": [{"material": nk(1.6), "circle": {"center": [0.2, 0.4],
                                                                                         "radius": 0.3}}]}])
# 1D: the CD (a metal stripe over a metal), a lossless stripe, two different stripes.
CD = rcwa.load_structure("cd")
STRIPE = structure([1.0], nk(1.0), nk(1.5), [
    {"thickness": 0.3, "material": nk(1.0), "shapes": [{"material": nk(2.0), "x": [0.1, 0.4]}]}])
TWO_STRIPES = structure([1.0], nk(1.0), nk(1.5), [
    {"thickness": 0.3, "material": nk(1.0), "shapes": [{"material": nk(2.0), "x": [0.1, 0.3]},
                                                       {"material": nk(1.5), "x": [0.45, 0.9]}]}])
# Order -1 of the 1 um grating at 600 nm has (kx, ky) = (s cos(phi) + 0.6, s sin(phi)),
# s = sin(theta): it grazes the air where its kt = 1, s = -0.6 cos(phi) + sqrt(0.36 cos(phi)^2 + 0.64).
_COS30 = math.cos(math.radians(30.0))
RAYLEIGH_THETA = math.degrees(math.asin(-0.6 * _COS30 + math.sqrt(0.36 * _COS30**2 + 0.64)))
# The substrate's index 1.5: order (-1, 0) of a 1 um period grazes the glass where
# 1.5 - sin(theta) cos(phi) ... = 1, i.e. at normal incidence for lambda = 1.5 um; and
# the air superstrate's (+-1, 0) at lambda = 1 um.
CASES = {
    "gold2d off its mirror planes": (GOLD2D, 600.0, 20.0, 30.0, 7),
    "asymmetric, oblique": (ASYMMETRIC, 650.0, 25.0, 40.0, 7),
    "asymmetric, normal incidence": (ASYMMETRIC, 650.0, 0.0, 0.0, 7),
    "asymmetric, Rayleigh point of the superstrate": (ASYMMETRIC, 1000.0, 0.0, 0.0, 5),
    "asymmetric, Rayleigh point of the substrate": (ASYMMETRIC, 1500.0, 0.0, 0.0, 5),
    "circle over gold, oblique": (CIRCLE_ON_GOLD, 550.0, 30.0, 60.0, 7),
    "1D metal stripe over aluminium, conical": (CD, 633.0, 20.0, 30.0, 31),
    "1D lossless stripe (real arithmetic), conical": (STRIPE, 600.0, 25.0, 40.0, 31),
    "1D lossless, symmetric about no point, conical": (TWO_STRIPES, 600.0, 25.0, 40.0, 31),
    "1D at a Rayleigh point of the superstrate, conical": (STRIPE, 600.0, RAYLEIGH_THETA, 30.0, 31),
}
# Free-standing layers (the substrate is the superstrate's medium): solved in even and odd
# halves (tests/rcwa/test_direct_symmetric.py says how, and checks what only they need).
FREE_STANDING = structure([1.0, 0.8], nk(1.0), nk(1.0), TWO_BLOCKS)
# 2 nm of gold blocks: X = exp(i kz k0 d) near 1, so I - X nearly cancels in the odd half.
THIN_GOLD = structure([1.0, 1.0], nk(1.0), nk(1.0), [
    {"thickness": 0.002, "material": nk(1.0), "shapes": [
        {"material": "gold", "rect": {"center": [0.3, 0.4], "size": [0.4, 0.3]}}]}])
# 1D off the classical mount (a lamellar layer solved directly), immersed in n = 1.3.
STRIPE_IMMERSED = structure([1.0], nk(1.3), nk(1.3), [
    {"thickness": 0.3, "material": nk(1.0), "shapes": [{"material": nk(2.0, 0.2), "x": [0.1, 0.4]}]}])
HALVES_CASES = {
    "gold2d at grazing-ish incidence (halves)": (GOLD2D, 550.0, 45.0, 10.0, 7),
    "free-standing blocks, oblique (halves)": (FREE_STANDING, 650.0, 25.0, 40.0, 7),
    # at 1000 nm and normal incidence orders (+-1, 0) graze the air on both sides (kz = 0)
    "free-standing blocks, Rayleigh point of both half-spaces (halves)": (FREE_STANDING, 1000.0, 0.0, 0.0, 5),
    "thin gold blocks (halves)": (THIN_GOLD, 600.0, 30.0, 20.0, 7),
    "1D lossy stripe immersed, conical (halves)": (STRIPE_IMMERSED, 600.0, 25.0, 40.0, 31),
}
CASES.update(HALVES_CASES)  # gold2d off its mirror planes, above, is free-standing too
AMPLITUDES = ("r_s_from_s", "r_p_from_s", "r_s_from_p", "r_p_from_p",
              "t_s_from_s", "t_p_from_s", "t_s_from_p", "t_p_from_p")


def _core_solve(s, wl, theta, phi, orders, fast_paths):
    """The core's solution without mirrors (so that only the direct path differs)."""
    prep = prepare(s, wl, orders)
    kx0, ky0 = incident_tangential_k(math.sqrt(prep.eps_sup.real), math.radians(theta), math.radians(phi))
    return _core.solve_stack(
        np.asarray(kx0 + prep.dkx, dtype=float), np.asarray(ky0 + prep.dky, dtype=float), prep.zero, prep.eps_sup,
        prep.eps_sub, s_direction(math.radians(phi)), prep.core_layers, STACK_METHOD_OF["etm"],
        INCIDENCE_OF["unpolarized"], fast_paths, [])


@pytest.mark.parametrize("name", CASES)
def test_direct_amplitudes_equal_the_etm(name):
    s, wl, theta, phi, orders = CASES[name]
    fast, general = _core_solve(s, wl, theta, phi, orders, True), _core_solve(s, wl, theta, phi, orders, False)
    assert fast.direct and not general.direct
    for got, want in ((fast.reflected, general.reflected), (fast.transmitted, general.transmitted)):
        assert np.all(np.isfinite(got))
        assert np.max(np.abs(got - want)) <= TOLERANCE_DIRECT * max(1.0, float(np.max(np.abs(want))))


@pytest.mark.parametrize("name", ["asymmetric, oblique", "free-standing blocks, oblique (halves)"])
@pytest.mark.parametrize("pol", ["s", "p", "unpolarized"])
def test_direct_efficiencies_equal_the_etm(pol, name):
    s, wl, theta, phi, orders = CASES[name]
    fast = rcwa.solve(s, wl, theta, phi, orders, pol)
    general = rcwa.solve(s, wl, theta, phi, orders, pol, fast_paths=False)
    assert fast.fast_paths == ("single_layer_direct",) and general.fast_paths == ()
    for key in ("R", "T", "T_into_substrate"):
        assert np.max(np.abs(fast.all_orders[key] - general.all_orders[key])) <= TOLERANCE_DIRECT
    for a, b in zip(fast.orders, general.orders, strict=True):
        for key in AMPLITUDES:
            assert abs(a.amplitudes[key] - b.amplitudes[key]) <= TOLERANCE_DIRECT * max(1.0, abs(b.amplitudes[key]))


def test_more_layers_and_one_dimensional_sweeps_keep_the_etm():
    two_layers = structure([1.0, 1.0], nk(1.0), nk(1.5), [
        {"thickness": 0.1, "material": nk(1.0), "shapes": [{"material": nk(2.0), "rect": {"center": [0.3, 0.3],
                                                                                           "size": [0.4, 0.2]}}]},
        {"thickness": 0.1, "material": nk(1.4)}])
    assert not _core_solve(two_layers, 600.0, 20.0, 30.0, 5, True).direct
    two_1d = structure([1.0], nk(1.0), nk(1.5), [
        {"thickness": 0.3, "material": nk(1.0), "shapes": [{"material": nk(2.0, 0.1), "x": [0.1, 0.4]}]},
        {"thickness": 0.1, "material": nk(1.0), "shapes": [{"material": nk(2.0), "x": [0.5, 0.6]}]}])
    assert not _core_solve(two_1d, 600.0, 20.0, 30.0, 21, True).direct
    assert _core_solve(STRIPE, 600.0, 20.0, 30.0, 21, True).direct
    # in classical mount TE and TM decouple, and one layer is solved directly per polarization
    # (polarized.hpp, solve_polarized_direct; against the general path: tests/rcwa/test_fast_paths.py)
    classical = _core_solve(STRIPE, 600.0, 20.0, 0.0, 21, True)
    assert classical.decoupled and classical.direct
    assert not _core_solve(two_1d, 600.0, 20.0, 0.0, 21, True).direct

"""A free-standing layer solved directly in even and odd halves gives the ETM's answer.

Where the substrate is the superstrate's medium, the one-layer stack is symmetric under
z -> d - z and rcwa/cpp/stack.cpp (solve_direct, direct_amplitudes) solves the even and
odd mode combinations c_d + c_u and c_d - c_u as two 2N x 2N systems instead of the 4N x 4N
one (a quarter of the factorization's work). In exact arithmetic it is the same solution,
so it agrees with the general path (the ETM through W^-1 and V^-1) to round-off: 1e-12
(issue 17's bound; measured <= 2.2e-15 on the 2D cases and 1.4e-14 on the lossy 1D one),
on every complex amplitude and on the efficiencies, for s, p and unpolarized light, also at
a Rayleigh point of both half-spaces at once, for a layer thin enough that X = exp(i kz d)
is close to 1 for every mode, and across the switch from the 4N system (a substrate that
differs from the superstrate by 1e-9 in permittivity) to the halves.
"""

import numpy as np
import pytest

import rcwa
from tests.rcwa.helpers import nk, structure
from tests.rcwa.test_direct import AMPLITUDES, _core_solve

TOLERANCE_DIRECT = 1e-12  # even/odd halves vs ETM (round-off only: the same boundary conditions)
# A substrate moved off the superstrate by 1e-9 in permittivity changes the amplitudes by
# about that much (the solution is smooth in eps_substrate); 1e-7 leaves room for the
# metal's amplification of it and is still far below any physical difference.
TOLERANCE_NEARBY = 1e-7

GOLD2D = rcwa.load_structure("gold2d")  # gold blocks in air, air on both sides
# Symmetric about no point and mirror-free, lossy and lossless blocks, in air.
FREE_STANDING = structure([1.0, 0.8], nk(1.0), nk(1.0), [
    {"thickness": 0.25, "material": nk(1.0), "shapes": [
        {"material": nk(2.2, 0.05), "rect": {"center": [0.3, 0.3], "size": [0.4, 0.2]}},
        {"material": nk(1.8), "rect": {"center": [0.7, 0.6], "size": [0.2, 0.3]}}]}])
# 2 nm of gold blocks: X = exp(i kz k0 d) near 1, so I - X nearly cancels in the odd half.
THIN_GOLD = structure([1.0, 1.0], nk(1.0), nk(1.0), [
    {"thickness": 0.002, "material": nk(1.0), "shapes": [
        {"material": "gold", "rect": {"center": [0.3, 0.4], "size": [0.4, 0.3]}}]}])
# 1D off the classical mount (a lamellar layer solved directly), immersed in n = 1.3.
STRIPE_IMMERSED = structure([1.0], nk(1.3), nk(1.3), [
    {"thickness": 0.3, "material": nk(1.0), "shapes": [{"material": nk(2.0, 0.2), "x": [0.1, 0.4]}]}])
CASES = {
    "gold2d off its mirror planes": (GOLD2D, 600.0, 20.0, 30.0, 7),
    "gold2d at grazing-ish incidence": (GOLD2D, 550.0, 45.0, 10.0, 7),
    "free-standing blocks, oblique": (FREE_STANDING, 650.0, 25.0, 40.0, 7),
    # at 1000 nm and normal incidence orders (+-1, 0) graze the air on both sides (kz = 0)
    "free-standing blocks, Rayleigh point of both half-spaces": (FREE_STANDING, 1000.0, 0.0, 0.0, 5),
    "thin gold blocks": (THIN_GOLD, 600.0, 30.0, 20.0, 7),
    "1D lossy stripe immersed, conical": (STRIPE_IMMERSED, 600.0, 25.0, 40.0, 31),
}


@pytest.mark.parametrize("name", CASES)
def test_even_odd_halves_equal_the_etm(name):
    s, wl, theta, phi, orders = CASES[name]
    assert s.superstrate.epsilon(wl) == s.substrate.epsilon(wl)
    fast, general = _core_solve(s, wl, theta, phi, orders, True), _core_solve(s, wl, theta, phi, orders, False)
    assert fast.direct and not general.direct
    for got, want in ((fast.reflected, general.reflected), (fast.transmitted, general.transmitted)):
        assert np.all(np.isfinite(got))
        assert np.max(np.abs(got - want)) <= TOLERANCE_DIRECT * max(1.0, float(np.max(np.abs(want))))


@pytest.mark.parametrize("pol", ["s", "p", "unpolarized"])
def test_even_odd_efficiencies_equal_the_etm(pol):
    s, wl, theta, phi, orders = CASES["free-standing blocks, oblique"]
    fast = rcwa.solve(s, wl, theta, phi, orders, pol)
    general = rcwa.solve(s, wl, theta, phi, orders, pol, fast_paths=False)
    assert fast.fast_paths == ("single_layer_direct",) and general.fast_paths == ()
    for key in ("R", "T", "T_into_substrate"):
        assert np.max(np.abs(fast.all_orders[key] - general.all_orders[key])) <= TOLERANCE_DIRECT
    for a, b in zip(fast.orders, general.orders, strict=True):
        for key in AMPLITUDES:
            assert abs(a.amplitudes[key] - b.amplitudes[key]) <= TOLERANCE_DIRECT * max(1.0, abs(b.amplitudes[key]))


def test_halves_and_full_system_meet():
    """A substrate 1e-9 off the superstrate takes the 4N x 4N system; its answer is the halves'."""
    wl, theta, phi, orders = 600.0, 20.0, 30.0, 7
    layers = [{"thickness": 1.0, "material": nk(1.0),
               "shapes": [{"material": "gold", "rect": {"center": [0.5, 0.5], "size": [0.5, 0.5]}}]}]
    same = structure([1.0, 1.0], nk(1.0), nk(1.0), layers)
    nearby = structure([1.0, 1.0], nk(1.0), nk(float(np.sqrt(1.0 + 1e-9))), layers)
    a, b = _core_solve(same, wl, theta, phi, orders, True), _core_solve(nearby, wl, theta, phi, orders, True)
    assert a.direct and b.direct
    assert np.max(np.abs(a.reflected - b.reflected)) <= TOLERANCE_NEARBY
    assert np.max(np.abs(a.transmitted - b.transmitted)) <= TOLERANCE_NEARBY

"""The core's fast paths give the general path's answer.

In a 1D stack at k_y = 0 (classical mount) TE and TM decouple in every layer and at both
half-spaces; the core then solves each polarization on N x N blocks, and only the one
asked for (rcwa/cpp/polarized.hpp). In exact arithmetic this is the same computation as
the 2N x 2N path with its zero blocks left out, so both must agree to round-off: 1e-12
(the issue's bound; measured <= 2e-15 on these cases), on efficiencies and on every
complex amplitude of every retained harmonic, including at a Rayleigh point, at normal
incidence, over a metal, and for a lossless layer next to a lossy one.
"""

import math

import numpy as np
import pytest

import rcwa
from rcwa import _core
from rcwa.solver import INCIDENCE_OF, STACK_METHOD_OF, prepare, s_direction
from tests.rcwa.helpers import lamellar, nk, structure
from workbench.core.conventions import incident_tangential_k

TOLERANCE_FAST = 1e-12  # fast path vs general path (round-off only: same algebra, fewer zeros)

# P2: the dielectric binary grating of Moharam, Grann, Pommet & Gaylord 1995 (JOSA A 12,
# 1068, Fig. 2: period 10 lambda, n = 2.04, fill 0.3, 10 deg), one wavelength deep.
P2 = structure([10.0], nk(1.0), nk(2.04), [
    {"thickness": 1.0, "material": nk(1.0), "shapes": [{"material": nk(2.04), "x": [0.0, 3.0]}]}])
MIXED = structure([1.0], nk(1.0), nk(1.5), [
    {"thickness": 0.3, "material": nk(1.0), "shapes": [{"material": nk(2.0), "x": [0.1, 0.4]}]},   # lossless
    {"thickness": 0.2, "material": nk(1.6, 0.05), "shapes": [{"material": nk(1.0, 0.05), "x": [0, 0.5]}]},  # lossy
    {"thickness": 0.1, "material": nk(2.0)},  # uniform
    {"thickness": 0.05, "material": nk(1.0), "shapes": [{"material": nk(0.2, 3.4), "x": [0.2, 0.7]}]}])  # metal
# Order -2 of a 1 um grating at 600 nm grazes the air superstrate where sin(theta) = 0.2.
RAYLEIGH_THETA = math.degrees(math.asin(0.2))

CASES = {
    "P2 oblique": (P2, 1000.0, 10.0, 41),
    "P2 normal incidence": (P2, 1000.0, 0.0, 41),
    "dielectric at a Rayleigh point": (lamellar(), 600.0, RAYLEIGH_THETA, 31),
    "cd at its Rayleigh point (normal)": (rcwa.load_structure("cd"), 400.0, 0.0, 31),
    "cd oblique, metal": (rcwa.load_structure("cd"), 633.0, 25.0, 31),
    "lossless next to lossy, metal below": (MIXED, 600.0, 20.0, 25),
}


def _core_solutions(s, wl, theta, orders, incidence):
    """The core's fast and general solutions of one classical-mount point."""
    prep = prepare(s, wl, orders)
    kx0, ky0 = incident_tangential_k(math.sqrt(prep.eps_sup.real), math.radians(theta), 0.0)
    args = (kx0 + prep.dkx, ky0 + prep.dky, prep.zero, prep.eps_sup, prep.eps_sub, s_direction(0.0), prep.core_layers,
            STACK_METHOD_OF["etm"], incidence)
    return _core.solve_stack(*args, fast_paths=True), _core.solve_stack(*args, fast_paths=False)


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("pol", ["s", "p", "unpolarized"])
def test_decoupled_amplitudes_equal_the_general_path(name, pol):
    s, wl, theta, orders = CASES[name]
    fast, general = _core_solutions(s, wl, theta, orders, INCIDENCE_OF[pol])
    assert fast.decoupled and not general.decoupled
    columns = {"s": [0], "p": [1], "unpolarized": [0, 1]}[pol]
    for got, want in ((fast.reflected, general.reflected), (fast.transmitted, general.transmitted)):
        scale = max(1.0, float(np.max(np.abs(want[:, columns]))))
        assert np.max(np.abs(got[:, columns] - want[:, columns])) <= TOLERANCE_FAST * scale
        # the polarization not asked for is not solved, and says so
        assert np.all(np.isnan(got[:, [c for c in (0, 1) if c not in columns]]))


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("pol", ["s", "p", "unpolarized"])
def test_decoupled_efficiencies_equal_the_general_path(name, pol):
    s, wl, theta, orders = CASES[name]
    fast = rcwa.solve(s, wl, theta, 0.0, orders, pol)
    general = rcwa.solve(s, wl, theta, 0.0, orders, pol, fast_paths=False)
    single = ("single_polarization",) if pol != "unpolarized" else ()
    assert fast.fast_paths == ("te_tm_decoupled",) + single and general.fast_paths == ()
    for key in ("R", "T", "T_into_substrate"):
        columns = {"s": [0], "p": [1], "unpolarized": [0, 1]}[pol]
        assert np.max(np.abs(fast.all_orders[key][:, columns] - general.all_orders[key][:, columns])) <= TOLERANCE_FAST
    for total in ("R_total", "T_total", "absorption"):
        assert abs(getattr(fast, total) - getattr(general, total)) <= TOLERANCE_FAST
    for a, b in zip(fast.orders, general.orders, strict=True):
        assert (a.m, a.R, a.T) == pytest.approx((b.m, b.R, b.T), abs=TOLERANCE_FAST)
        for key, value in a.amplitudes.items():
            if key.endswith("from_s") == (pol != "p") or pol == "unpolarized":
                assert abs(value - b.amplitudes[key]) <= TOLERANCE_FAST * max(1.0, abs(value))


def test_single_polarization_leaves_the_other_unsolved():
    result = rcwa.solve(P2, 1000.0, 10.0, 0.0, 21, "s")
    order = result.order(0)
    assert math.isfinite(order.R_s) and math.isnan(order.R_p)
    assert np.isnan(order.amplitudes["r_p_from_p"]) and np.isfinite(order.amplitudes["r_s_from_s"])


@pytest.mark.parametrize(("theta", "phi", "stack"), [
    (10.0, 30.0, "etm"),   # conical: k_y != 0 couples TE and TM
    (0.0, 90.0, "etm"),    # normal incidence, s-hat along -x: the specular order's s is TM-like
    (10.0, 0.0, "smatrix"),  # the fast path is written for the ETM stack only
])
def test_coupled_or_other_stacks_take_the_general_path(theta, phi, stack):
    result = rcwa.solve(P2, 1000.0, theta, phi, 21, "s", stack=stack)
    assert result.fast_paths == ()
    assert all(math.isfinite(o.R_p) for o in result.orders)


def test_two_dimensional_cells_take_the_general_path():
    result = rcwa.solve(rcwa.load_structure("gold2d"), 550.0, 0.0, 0.0, (5, 5), "s")
    assert result.fast_paths == ()

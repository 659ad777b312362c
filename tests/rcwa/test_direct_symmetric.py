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

from tests.rcwa.helpers import nk, structure
from tests.rcwa.test_direct import CASES, HALVES_CASES, _core_solve

# The comparisons with the ETM, amplitudes and efficiencies, run in tests/rcwa/test_direct.py
# over its CASES, which include these (HALVES_CASES) and gold2d off its mirror planes.
# A substrate moved off the superstrate by 1e-9 in permittivity changes the amplitudes by
# about that much (the solution is smooth in eps_substrate); 1e-7 leaves room for the
# metal's amplification of it and is still far below any physical difference.
TOLERANCE_NEARBY = 1e-7


@pytest.mark.parametrize("name", [*HALVES_CASES, "gold2d off its mirror planes"])
def test_the_halves_cases_are_free_standing_and_solved_directly(name):
    s, wl, theta, phi, orders = CASES[name]
    assert s.superstrate.epsilon(wl) == s.substrate.epsilon(wl)
    assert _core_solve(s, wl, theta, phi, orders, True).direct


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

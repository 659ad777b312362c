"""Uniform stacks against the analytic Airy/Fresnel result (an independent recursion).

Tolerance: 1e-10 absolute in R and T. Both computations are exact in exact arithmetic
(a uniform stack couples no orders), so only round-off separates them; 1e-10 leaves
four orders of magnitude for it.
"""

import pytest

import rcwa
from tests.rcwa.helpers import airy_rt, nk, structure

TOLERANCE_THIN_FILM = 1e-10

CASES = {
    "single dielectric slab": ([nk(1.0), nk(2.1), nk(1.52)], [0.37]),
    "dielectric multilayer": ([nk(1.33), nk(2.3), nk(1.45), nk(2.3), nk(1.45), nk(1.52)], [0.06, 0.1, 0.06, 0.1]),
    "thin metal film on glass": ([nk(1.0), nk(0.27, 2.9), nk(1.5)], [0.03]),
    "metal substrate under a dielectric": ([nk(1.0), nk(1.58), nk(1.2, 7.0)], [0.11]),
    "lossy multilayer": ([nk(1.0), nk(0.5, 2.0), nk(1.5, 0.02), nk(3.9, 0.02), nk(1.46)], [0.02, 0.2, 0.05]),
}


def _stack(ns, ds):
    return structure([1.0], ns[0], ns[-1], [{"thickness": d, "material": n} for n, d in zip(ns[1:-1], ds, strict=True)])


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("pol", ["s", "p"])
@pytest.mark.parametrize("theta", [0.0, 35.0, 71.0])
def test_uniform_stack_matches_airy(name, pol, theta):
    ns, ds = CASES[name]
    result = rcwa.solve(_stack(ns, ds), 633.0, theta, 20.0, 5, pol)
    R, T = airy_rt([complex(n["n"], n["k"]) for n in ns], ds, 633.0, theta, pol)
    assert result.R_total == pytest.approx(R, abs=TOLERANCE_THIN_FILM)
    assert result.T_total == pytest.approx(T, abs=TOLERANCE_THIN_FILM)
    # Only the specular order carries power through a uniform stack.
    assert [(o.m, o.n) for o in result.orders if o.R > 1e-14 or o.T > 1e-14] == [(0, 0)]


@pytest.mark.parametrize("pol", ["s", "p"])
def test_bare_interface_is_fresnel(pol):
    R, T = airy_rt([1.0, 1.5], [], 550.0, 40.0, pol)
    result = rcwa.solve(_stack([nk(1.0), nk(1.5)], []), 550.0, 40.0, 0.0, 1, pol)
    assert result.R_total == pytest.approx(R, abs=TOLERANCE_THIN_FILM)
    assert result.R_total + result.T_total == pytest.approx(1.0, abs=TOLERANCE_THIN_FILM)


def test_2d_uniform_stack_matches_airy():
    ns, ds = CASES["lossy multilayer"]
    s = structure([1.0, 0.8], ns[0], ns[-1], [{"thickness": d, "material": n} for n, d in zip(ns[1:-1], ds, strict=True)])
    for pol in ("s", "p"):
        result = rcwa.solve(s, 500.0, 25.0, 60.0, (3, 3), pol)
        R, T = airy_rt([complex(n["n"], n["k"]) for n in ns], ds, 500.0, 25.0, pol)
        assert result.R_total == pytest.approx(R, abs=TOLERANCE_THIN_FILM)
        assert result.T_total == pytest.approx(T, abs=TOLERANCE_THIN_FILM)

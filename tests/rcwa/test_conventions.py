"""The order-numbering, angle and polarization conventions (workbench.core.conventions).

Order m leaves with k_x,m = k_x,inc - m * 2 pi / Lambda (Lange et al. 2021, Eq. 2): its
reflected direction must satisfy n1 sin(theta_m) cos(phi_m) = n1 sin(theta) cos(phi)
- m lambda / Lambda, computed here independently of the solver. Tolerance 1e-12 deg-free
(direction cosines): both are closed-form evaluations.
"""

import math

import pytest

import rcwa
from tests.rcwa.helpers import lamellar, nk, structure


def test_orders_leave_where_the_grating_equation_puts_them():
    period, wl, theta, phi = 1.6, 532.0, 25.0, 30.0
    s = lamellar(period=period, depth=0.1, n_ridge=nk(0.5, 3.0), sub=nk(0.5, 3.0))
    r = rcwa.solve(s, wl, theta, phi, 41, "unpolarized")
    kx0 = math.sin(math.radians(theta)) * math.cos(math.radians(phi))
    ky0 = math.sin(math.radians(theta)) * math.sin(math.radians(phi))
    assert len(r.orders) >= 4
    for o in r.orders:
        th, ph = map(math.radians, o.direction_R)
        assert math.sin(th) * math.cos(ph) == pytest.approx(kx0 - o.m * wl / 1000 / period, abs=1e-12)
        assert math.sin(th) * math.sin(ph) == pytest.approx(ky0, abs=1e-12)


def test_positive_orders_go_toward_minus_x():
    """At normal incidence order +1 has k_x = -lambda/Lambda < 0: azimuth 180 deg."""
    r = rcwa.solve(lamellar(period=1.0), 500.0, 0.0, 0.0, 21, "s")
    assert r.order(1).direction_R[1] == pytest.approx(180.0)
    assert r.order(-1).direction_R[1] == pytest.approx(0.0)


def test_s_polarization_is_te_in_classical_mount():
    """s at phi = 0 has E along the grooves (y): a y-invariant metal wire grid reflects it strongly."""
    wires = lamellar(period=0.2, depth=0.2, n_ridge=nk(0.5, 5.0), n_groove=nk(1.0), sub=nk(1.0), fill=(0.0, 0.1))
    s = rcwa.solve(wires, 600.0, 0.0, 0.0, 21, "s")
    p = rcwa.solve(wires, 600.0, 0.0, 0.0, 21, "p")
    assert s.R_total > 0.5 > p.R_total  # a wire-grid polarizer reflects E parallel to the wires


def test_2d_order_indices_follow_both_periods():
    s = structure([1.0, 1.5], nk(1.0), nk(1.5), [{"thickness": 0.2, "material": nk(1.0),
                  "shapes": [{"material": nk(2.0), "circle": {"center": [0.3, 0.4], "radius": 0.25}}]}])
    wl = 450.0
    r = rcwa.solve(s, wl, 10.0, 70.0, (5, 5), "unpolarized")
    kx0 = math.sin(math.radians(10)) * math.cos(math.radians(70))
    ky0 = math.sin(math.radians(10)) * math.sin(math.radians(70))
    for o in r.orders:
        if o.direction_R:
            th, ph = map(math.radians, o.direction_R)
            assert math.sin(th) * math.cos(ph) == pytest.approx(kx0 - o.m * wl / 1000 / 1.0, abs=1e-12)
            assert math.sin(th) * math.sin(ph) == pytest.approx(ky0 - o.n * wl / 1000 / 1.5, abs=1e-12)

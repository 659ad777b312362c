"""The conventions module's own functions (workbench/core/conventions.py).

tests/rcwa/test_conventions.py checks that the solver's orders leave where the grating
equation puts them, and tests/rcwa/test_core_boundary.py that the C++ core's offsets and
half-space kz agree with these functions; here, the functions themselves: the order sign of
Lange et al. 2021 Eq. 2, the outgoing kz branch and its round-off guard, the incident
tangential wave vector. TOLERANCE = 1e-15: each value is a handful of floating-point
operations on numbers of order 1.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from workbench.core.conventions import (
    ORDER_SIGN,
    Polarization,
    incident_tangential_k,
    kz_branch,
    order_kx,
    order_kxy,
)

TOLERANCE = 1e-15


def test_order_sign_is_lange_eq2():
    """k_x,m = k_x,inc - m lambda / Lambda: order +1 moves toward -x."""
    assert ORDER_SIGN == -1
    kx = order_kx(0.3, np.array([-1, 0, 1, 2]), 1.6, 0.5)
    np.testing.assert_allclose(kx, 0.3 - np.array([-1, 0, 1, 2]) * 0.5 / 1.6, atol=TOLERANCE)


def test_order_kxy_applies_the_sign_on_each_axis():
    m, n = np.meshgrid([-1, 0, 1], [-2, 0, 2], indexing="ij")
    kx, ky = order_kxy(0.1, -0.2, m, n, (1.0, 2.0), 0.55)
    np.testing.assert_allclose(kx, order_kx(0.1, m, 1.0, 0.55), atol=TOLERANCE)
    np.testing.assert_allclose(ky, order_kx(-0.2, n, 2.0, 0.55), atol=TOLERANCE)
    kx1, ky1 = order_kxy(0.1, -0.2, np.array([-1, 0, 1]), 0, (1.0,), 0.55)  # 1D: ky stays the incident one
    np.testing.assert_allclose(ky1, [-0.2] * 3, atol=0)
    np.testing.assert_allclose(kx1, kx[:, 1], atol=TOLERANCE)


def test_a_1d_grating_has_no_y_orders():
    with pytest.raises(ValueError, match="only n = 0"):
        order_kxy(0.0, 0.0, np.array([0, 1]), np.array([0, 1]), (1.0,), 0.5)


def test_kz_branch_is_outgoing():
    """Im(kz) >= 0, and Re(kz) >= 0 where Im(kz) == 0; kz^2 comes back."""
    rng = np.random.default_rng(0)
    z2 = rng.normal(size=200) + 1j * rng.normal(size=200)
    z2 = np.concatenate([z2, [-2.0 + 0j, 2.0 + 0j, 0j, -2.0 - 0.0j, 2.0 - 0.0j, -1e-30 + 1e-300j]])
    kz = kz_branch(z2)
    assert np.all(kz.imag >= 0)
    assert np.all(kz.real[kz.imag == 0] >= 0)
    np.testing.assert_allclose(kz**2, z2, rtol=1e-14, atol=1e-300)


def test_a_round_off_minus_zero_does_not_flip_a_propagating_wave():
    """numpy's sqrt(x - 0j) is on the branch cut; a lossless half-space must keep +sqrt(x),
    and an evanescent one +i sqrt(|x|)."""
    assert kz_branch(np.array([complex(0.64, -0.0)]))[0] == 0.8
    assert kz_branch(np.array([complex(-0.64, -0.0)]))[0] == 0.8j


def test_incident_tangential_k_points_along_phi():
    kx, ky = incident_tangential_k(1.5, math.radians(30.0), math.radians(120.0))
    assert math.hypot(kx, ky) == pytest.approx(1.5 * 0.5, abs=TOLERANCE)
    assert math.degrees(math.atan2(ky, kx)) == pytest.approx(120.0, abs=1e-12)


def test_polarizations_are_named_as_in_files():
    assert [p.value for p in Polarization] == ["s", "p", "unpolarized"]
    assert Polarization("p") is Polarization.P


def test_incident_tangential_k_of_many_directions_equals_one_at_a_time():
    """The sweep passes arrays, a single solve scalars: the same rule either way."""
    theta = np.radians([0.0, 10.0, 45.0, 89.999])
    phi = np.radians([0.0, 90.0, 200.0, 315.0])
    kx, ky = incident_tangential_k(1.33, theta, phi)
    one = [incident_tangential_k(1.33, float(t), float(p)) for t, p in zip(theta, phi, strict=True)]
    assert all(type(v) is float for pair in one for v in pair)
    np.testing.assert_allclose(np.stack([kx, ky], 1), one, atol=TOLERANCE)

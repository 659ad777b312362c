"""Kernel lookups against scipy's interpolator on the same table (independent reference).

Tolerance 1e-5: float32 data and float32 kernel arithmetic (relative 6e-8 per operation)
against float64 interpolation of the same float32 values.
"""

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

TOLERANCE_LOOKUP = 1e-5


def test_lookup_matches_scipy_and_folds_azimuths(mitsuba_variant, cd_table):
    import mitsuba as mi

    from renderer.efficiency import EfficiencyLookup

    look = EfficiencyLookup.from_table(cd_table)
    values = cd_table.arrays["R"][..., cd_table.meta["pol_names"].index("unpolarized")]
    interp = RegularGridInterpolator((cd_table.wavelengths_nm, cd_table.theta_deg, cd_table.phi_deg), values)
    rng = np.random.default_rng(1)
    n = 400
    wl = rng.uniform(380, 780, n)
    theta = rng.uniform(0, 89.99, n)
    phi = rng.uniform(-360, 720, n)
    k = rng.integers(0, look.order_count, n)
    got = np.array(look.eval(mi.UInt32(k), mi.Float(wl), mi.Float(theta), mi.Float(phi)))
    for i in range(n):
        folded, flip_m, flip_n, _ = cd_table.fold_azimuth(phi[i])  # 1D: never a swap
        m, nn = cd_table.orders[k[i]]
        q = cd_table.orders.index((-m if flip_m else m, -nn if flip_n else nn))
        expected = interp([wl[i], theta[i], folded])[0][q]
        assert got[i] == pytest.approx(expected, abs=TOLERANCE_LOOKUP)


def test_wavelengths_outside_the_table_give_zero(mitsuba_variant, cd_table):
    import mitsuba as mi

    from renderer.efficiency import EfficiencyLookup

    look = EfficiencyLookup.from_table(cd_table)
    out = np.array(look.eval(mi.UInt32([3, 3, 3]), mi.Float([300.0, 379.0, 900.0]), mi.Float([10.0] * 3), mi.Float([5.0] * 3)))
    assert np.all(out == 0) and np.all(np.isfinite(out))

"""``superstrate_index``: a CD's top rendered at its mean index is the grating's superstrate (renderer/bwdf.py).

The top refracts at one index n_top; the orders' directions under it must use the same
index, so that a flat slab keeps the tangential wave vector from air to the grating and
back: then every sampled order satisfies the grating equation (Lange et al. 2021, Eq. 2)
in tangential wave vectors n_top * omega_t, at the wavelength it carries. Without the
setting the orders follow the table's n(lambda) instead, which misses n_top's grating
equation by up to |1 - n_top / n(lambda)| * |k| (about 1e-2 here): the check can fail.
"""

import math

import numpy as np
import pytest

from workbench.core.conventions import ORDER_SIGN

WAVELENGTHS = (420.0, 500.0, 580.0, 680.0)
N_TOP = 1.59  # polycarbonate's mean index (renderer.dielectric.mean_index)
WI = (0.31, 0.17, math.sqrt(1 - 0.31**2 - 0.17**2))  # toward the camera, inside the top
SAMPLES = 4000
ORDER_TOL = 1e-4  # float32 directions: the implied order is an integer to about 1e-5


def _samples(table_path, **props):
    import drjit as dr
    import mitsuba as mi

    from renderer.bwdf import register

    register()
    bsdf = mi.load_dict({"type": "bwdf", "filename": str(table_path), **props})
    si = dr.zeros(mi.SurfaceInteraction3f, SAMPLES)
    si.wi = mi.Vector3f(*WI)
    si.wavelengths = mi.Spectrum(*WAVELENGTHS)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    u1 = mi.Float(((np.arange(SAMPLES) + 0.5) / SAMPLES).astype(np.float32))
    ctx = mi.BSDFContext(mi.TransportMode.Radiance, mi.BSDFFlags.All)
    bs, w = bsdf.sample(ctx, si, u1, mi.Point2f(0.5, 0.5))
    return bsdf, np.array(bs.wo), np.array(w), np.array(bs.pdf)


def _period() -> float:
    import rcwa

    return float(rcwa.load_structure("cd").period[0])  # the cd_table fixture's structure


def _implied_orders(wo, w, pdf, n, period_um):
    """For each diffracted sample (one lane carries it), the order its directions imply at index n."""
    orders = []
    for j in np.flatnonzero(pdf > 0):
        lanes = np.flatnonzero(w[:, j] > 0)
        if len(lanes) != 1:  # the specular order keeps every wavelength: its direction is the mirror one at any n
            continue
        lam = WAVELENGTHS[lanes[0]]
        k_out, k_inc = n * WI[0], -n * wo[0, j]
        assert abs(n * WI[1] + n * wo[1, j]) < 1e-5  # along the grooves nothing changes
        orders.append((k_out - k_inc) * 1000.0 * period_um / (ORDER_SIGN * lam))
    return np.array(orders)


def test_orders_follow_the_top_index(mitsuba_variant, cd_table):
    bsdf, wo, w, pdf = _samples(cd_table.path, superstrate_index=N_TOP)
    assert "superstrate_index = 1.59" in str(bsdf)
    period = _period()
    orders = _implied_orders(wo, w, pdf, N_TOP, period)
    assert len(orders) > 100 and len(np.unique(np.round(orders))) >= 2  # several diffracted orders sampled
    assert np.max(np.abs(orders - np.round(orders))) < ORDER_TOL


def test_without_it_the_orders_follow_the_tables_index(mitsuba_variant, cd_table):
    _, wo, w, pdf = _samples(cd_table.path)
    period = _period()
    orders = _implied_orders(wo, w, pdf, N_TOP, period)
    assert np.max(np.abs(orders - np.round(orders))) > 100 * ORDER_TOL  # n(lambda), not N_TOP: the check can fail


@pytest.mark.parametrize("value", [0.5, float("nan"), -1.6])
def test_an_index_below_one_is_refused(mitsuba_variant, cd_table, value):
    import mitsuba as mi

    from renderer.bwdf import register

    register()
    with pytest.raises(RuntimeError, match="superstrate_index"):
        mi.load_dict({"type": "bwdf", "filename": str(cd_table.path), "superstrate_index": value})

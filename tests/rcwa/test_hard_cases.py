"""Hard cases stay finite and correct.

Tolerances, each with its reason:
* TOLERANCE_EXACT = 1e-10: identities that hold exactly in the truncated problem (a
  zero-thickness layer, a layer without contrast, analytic thin films), so round-off only.
* TOLERANCE_ENERGY = 1e-9: R + T = 1 for lossless structures (Hermitian truncation).
* Rayleigh anomalies: efficiencies vary like sqrt(|lambda - lambda_R|) near one; 1e-6 nm
  away (relative 2.5e-9) that is a change of order 1e-4, so TOLERANCE_RAYLEIGH = 1e-3
  checks continuity with a margin and would catch a NaN, a jump or a lost order.
"""

import math

import numpy as np
import pytest

import rcwa
from tests.rcwa.helpers import airy_rt, lamellar, nk, structure

TOLERANCE_EXACT = 1e-10
TOLERANCE_ENERGY = 1e-9
TOLERANCE_RAYLEIGH = 1e-3


def _finite(result) -> bool:
    values = [result.R_total, result.T_total] + [v for o in result.orders for v in (o.R, o.T)]
    return all(math.isfinite(v) for v in values)


@pytest.mark.parametrize("k", [0.0, 0.01])
def test_100_um_thick_uniform_layer_matches_airy(k):
    ns = [nk(1.0), nk(1.7, k), nk(1.5)]
    s = structure([1.0], ns[0], ns[-1], [{"thickness": 100.0, "material": ns[1]}])
    for pol in ("s", "p"):
        r = rcwa.solve(s, 550.0, 30.0, 0.0, 5, pol)
        R, T = airy_rt([complex(n["n"], n["k"]) for n in ns], [100.0], 550.0, 30.0, pol)
        assert r.R_total == pytest.approx(R, abs=1e-8)  # phase k0 n d ~ 2000 rad: 1e-8 for its round-off
        assert r.T_total == pytest.approx(T, abs=1e-8)


def test_100_um_thick_grating_lossless_and_lossy():
    lossless = lamellar(period=1.0, depth=100.0, n_ridge=nk(1.6), n_groove=nk(1.0))
    r = rcwa.solve(lossless, 600.0, 20.0, 30.0, 41, "unpolarized")
    assert _finite(r) and abs(r.R_total + r.T_total - 1) < TOLERANCE_ENERGY
    # A lossy 100 um layer is opaque: nothing transmits, and the reflection equals that of
    # the same grating layer 50 um thick (light never reaches the bottom).
    lossy = lamellar(period=1.0, depth=100.0, n_ridge=nk(1.6, 0.05), n_groove=nk(1.0, 0.05))
    half = lamellar(period=1.0, depth=50.0, n_ridge=nk(1.6, 0.05), n_groove=nk(1.0, 0.05))
    a, b = rcwa.solve(lossy, 600.0, 20.0, 30.0, 41, "p"), rcwa.solve(half, 600.0, 20.0, 30.0, 41, "p")
    assert _finite(a) and a.T_total < 1e-12
    assert a.R_total == pytest.approx(b.R_total, abs=TOLERANCE_EXACT)


def test_grazing_incidence_89_9_deg():
    s = structure([1.0], nk(1.0), nk(1.5), [])
    for pol in ("s", "p"):
        r = rcwa.solve(s, 550.0, 89.9, 0.0, 3, pol)
        R, _ = airy_rt([1.0, 1.5], [], 550.0, 89.9, pol)
        assert r.R_total == pytest.approx(R, abs=TOLERANCE_EXACT)
    g = rcwa.solve(lamellar(), 550.0, 89.9, 10.0, 41, "unpolarized")
    assert _finite(g) and abs(g.R_total + g.T_total - 1) < TOLERANCE_ENERGY


@pytest.mark.parametrize("superstrate", ["air", "polycarbonate"])
def test_rayleigh_anomaly_exactly_on_the_grid(superstrate):
    """An order grazing the superstrate exactly (k_z = 0), as on the paper's CD grid.

    CD in air at 400 nm, normal incidence: orders +-4 have k_x = 4 * 0.4 / 1.6 = 1 = n_air.
    Under polycarbonate the wavelength is chosen so that order 3 grazes exactly.
    """
    s = rcwa.Structure.from_dict({
        "period": [1.6], "superstrate": superstrate, "substrate": "aluminum",
        "layers": [{"thickness": 0.11, "material": "polycarbonate", "shapes": [{"material": "aluminum", "x": [0.5, 1.1]}]}],
    })
    if superstrate == "air":
        wavelength, order = 400.0, 4
    else:
        from rcwa.materials import material_from_spec

        pc = material_from_spec("polycarbonate")
        wavelength = 480.0
        for _ in range(60):  # fixed point of 3 * lambda / 1.6 um = n_pc(lambda)
            wavelength = 1600.0 * float(pc.refractive_index(wavelength).real) / 3.0
        order = 3
    at = rcwa.solve(s, wavelength, 0.0, 0.0, 61, "unpolarized")
    assert _finite(at)
    kz = at.all_orders["kz_superstrate"][list(at.all_orders["m"]).index(order)]
    assert abs(kz) < 1e-6  # really on the anomaly
    for side in (-1e-6, 1e-6):
        near = rcwa.solve(s, wavelength + side, 0.0, 0.0, 61, "unpolarized")
        assert near.R_total == pytest.approx(at.R_total, abs=TOLERANCE_RAYLEIGH)
        for o in at.orders:
            if o.m != order:
                assert near.order(o.m).R == pytest.approx(o.R, abs=TOLERANCE_RAYLEIGH)


def test_rayleigh_anomaly_lossless_conserves_energy():
    s = lamellar(period=1.6, depth=0.3, n_ridge=nk(1.6), n_groove=nk(1.0), sub=nk(1.5))
    r = rcwa.solve(s, 400.0, 0.0, 0.0, 61, "unpolarized")
    assert _finite(r) and abs(r.R_total + r.T_total - 1) < TOLERANCE_ENERGY


def test_normal_incidence_is_continuous_and_azimuth_free():
    s = lamellar(n_ridge=nk(0.3, 3.0), n_groove=nk(1.0), sub=nk(0.3, 3.0))
    at = rcwa.solve(s, 550.0, 0.0, 0.0, 41, "unpolarized")
    for phi in (37.0, 90.0):
        assert rcwa.solve(s, 550.0, 0.0, phi, 41, "unpolarized").R_total == pytest.approx(at.R_total, abs=TOLERANCE_EXACT)
    near = rcwa.solve(s, 550.0, 1e-7, 0.0, 41, "unpolarized")
    assert near.R_total == pytest.approx(at.R_total, abs=1e-8)
    # Symmetric cell at normal incidence: orders +m and -m carry the same power.
    sym = lamellar(fill=(0.25, 0.75))
    r = rcwa.solve(sym, 550.0, 0.0, 0.0, 41, "s")
    assert r.order(1).T == pytest.approx(r.order(-1).T, abs=TOLERANCE_EXACT)


def test_many_orders_1d_301():
    s = lamellar(n_ridge=nk(1.2, 7.0), n_groove=nk(1.0), sub=nk(1.2, 7.0), depth=0.3)
    r = rcwa.solve(s, 633.0, 10.0, 20.0, 301, "p")
    r201 = rcwa.solve(s, 633.0, 10.0, 20.0, 201, "p")
    assert _finite(r)
    assert r.R_total == pytest.approx(r201.R_total, abs=2e-4)  # converging, not drifting
    d = rcwa.solve(lamellar(), 633.0, 10.0, 20.0, 301, "unpolarized")
    assert abs(d.R_total + d.T_total - 1) < TOLERANCE_ENERGY


@pytest.mark.slow
def test_many_orders_2d_25x25():
    s = structure([1.0, 1.0], nk(1.0), nk(1.5), [{"thickness": 0.3, "material": nk(1.0),
                  "shapes": [{"material": nk(2.0), "rect": {"center": [0.5, 0.5], "size": [0.5, 0.5]}}]}])
    r = rcwa.solve(s, 550.0, 10.0, 20.0, (25, 25), "unpolarized")
    assert _finite(r) and abs(r.R_total + r.T_total - 1) < TOLERANCE_ENERGY


def test_zero_thickness_layer_is_no_layer():
    base = structure([1.0], nk(1.0), nk(1.5), [{"thickness": 0.2, "material": nk(2.0)}])
    extra = structure([1.0], nk(1.0), nk(1.5), [
        {"thickness": 0.0, "material": nk(1.0), "shapes": [{"material": nk(0.3, 4.0), "x": [0.0, 0.4]}]},
        {"thickness": 0.2, "material": nk(2.0)},
        {"thickness": 0.0, "material": nk(3.0)},
    ])
    for pol in ("s", "p"):
        a, b = rcwa.solve(base, 600.0, 30.0, 45.0, 21, pol), rcwa.solve(extra, 600.0, 30.0, 45.0, 21, pol)
        assert b.R_total == pytest.approx(a.R_total, abs=TOLERANCE_EXACT)
        assert b.T_total == pytest.approx(a.T_total, abs=TOLERANCE_EXACT)


@pytest.mark.parametrize("layers", [[], [{"thickness": 0.0, "material": nk(1.0)}]], ids=["no layer", "zero-thickness layer"])
@pytest.mark.parametrize("stack", ["etm", "smatrix"])
def test_bare_interface_at_a_rayleigh_point(layers, stack):
    """Air on air with nothing (or nothing thick) between, at 400 nm and normal incidence on
    a 0.8 um period: orders +-2 graze both half-spaces (k_z = 0). Found by the hypothesis
    energy test: the matching system was singular. Nothing scatters, so T_0 = 1 and the
    rest 0, to round-off."""
    s = structure([0.8], nk(1.0), nk(1.0), layers)
    for pol in ("s", "p"):
        r = rcwa.solve(s, 400.0, 0.0, 0.0, 11, pol, stack=stack)
        assert _finite(r) and r.order(0).T == pytest.approx(1.0, abs=TOLERANCE_EXACT)
        assert r.R_total == pytest.approx(0.0, abs=TOLERANCE_EXACT)


def test_layer_without_contrast_is_uniform():
    same = structure(
        [1.0], nk(1.0), nk(1.5), [{"thickness": 0.3, "material": "gold", "shapes": [{"material": "gold", "x": [0.2, 0.7]}]}]
    )
    uniform = structure([1.0], nk(1.0), nk(1.5), [{"thickness": 0.3, "material": "gold"}])
    for pol in ("s", "p"):
        a, b = rcwa.solve(same, 600.0, 30.0, 45.0, 21, pol), rcwa.solve(uniform, 600.0, 30.0, 45.0, 21, pol)
        assert a.R_total == pytest.approx(b.R_total, abs=TOLERANCE_EXACT)
    # The eigen-solve path itself agrees too (a shape of a material with the same index).
    twin_shape = {"material": nk(1.7, 0.1 + 1e-13), "x": [0.2, 0.7]}
    twin = structure([1.0], nk(1.0), nk(1.5), [{"thickness": 0.3, "material": nk(1.7, 0.1), "shapes": [twin_shape]}])
    one = structure([1.0], nk(1.0), nk(1.5), [{"thickness": 0.3, "material": nk(1.7, 0.1)}])
    assert rcwa.solve(twin, 600.0, 30.0, 45.0, 21, "p").R_total == pytest.approx(
        rcwa.solve(one, 600.0, 30.0, 45.0, 21, "p").R_total, abs=1e-9)


def test_all_orders_arrays_are_finite_for_metal_at_grazing_order():
    r = rcwa.solve(rcwa.load_structure("cd"), 400.0, 0.0, 0.0, 61, "unpolarized")
    assert np.all(np.isfinite(r.all_orders["R"])) and np.all(np.isfinite(r.all_orders["T"]))


def test_refined_sweep_through_rayleigh_points_conserves_energy():
    # The sweep refines each k_x's eigen-solve from its neighbour's (rcwa/cpp/sweep.hpp).
    # A deep, high-contrast lossless grating swept in 1 deg steps, with Rayleigh points on
    # the grid (500 nm over a 1 um period: order -1 grazes at theta = 30 deg, phi = 0):
    # every point stays finite and conserves energy, and most solves took the refined path.
    from rcwa.sweep import sweep_directions

    s = lamellar(period=1.0, depth=1.0, n_ridge=nk(3.5), n_groove=nk(1.0), fill=(0.0, 0.4))
    theta, phi = (a.ravel() for a in np.meshgrid(np.arange(0.0, 89.0, 1.0), [0.0, 45.0], indexing="ij"))
    sw = sweep_directions(s, 500.0, theta, phi, 41, threads=2)
    assert sw.eigen_refined > 0.5 * sw.eigen_solves, (sw.eigen_refined, sw.eigen_solves)
    total = sw.R.sum(axis=1) + sw.T.sum(axis=1)
    assert np.all(np.isfinite(total))
    assert np.abs(total - 1.0).max() < TOLERANCE_ENERGY

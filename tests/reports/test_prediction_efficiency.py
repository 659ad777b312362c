"""renderer/trace/efficiency_weights.py: the prediction's efficiency weighting, checked against independent computations.

The prediction weighs each lit (pixel, wavelength) of order m by the order's RCWA efficiency
at the incident wave's direction (the scene's table) and by the flat top's Fresnel
transmission for the camera's ray and the light's. Here those weights are computed again
from their definitions: the incident wave from the grating equation (Lange et al. 2021,
Eq. 2, workbench.core.conventions.order_kx), its direction inside the superstrate by
Snell's law, the table read by scipy's trilinear interpolator after rcwa.table's own
azimuth fold, and Fresnel's transmission in Born & Wolf's sine/tangent form.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from rcwa.table import Table
from renderer.render import with_resolution
from renderer.scene import load_scene
from renderer.trace import efficiency_weights as prediction_efficiency
from renderer.trace import prediction
from workbench.core.conventions import order_kx

RESOLUTION = (160, 120)  # small: the weights do not depend on the pixel count
ROUND_OFF = 1e-9  # float64 arithmetic on float32 table values: the same numbers by two routes agree to round-off
WEIGHT_TOLERANCE = 1e-6  # a pixel's weighted sum over up to 56 wavelengths, by two routes (relative)
PIXELS_CHECKED = 6
MATTERS = 0.1  # measured 0.32: order -1's lit share at some pixel moves by more than this with the weighting


def _scene(top: bool):
    spec = with_resolution(load_scene("cornell_cd_view2"), RESOLUTION)
    return dataclasses.replace(spec, cds=tuple(dataclasses.replace(cd, top_surface=top) for cd in spec.cds))


@pytest.fixture(scope="module")
def efficiency() -> prediction_efficiency.Efficiency:
    return prediction_efficiency.scene_efficiency(_scene(top=True))


def _table_interpolator(eff: prediction_efficiency.Efficiency, m: int) -> RegularGridInterpolator:
    k = eff.orders_m.index(m)
    return RegularGridInterpolator((eff.wavelengths_nm, eff.theta_deg, eff.phi_deg), eff.values[..., k])


def _stored(eff: prediction_efficiency.Efficiency) -> Table:
    """rcwa.table's reader over the same metadata, for its scalar fold_azimuth."""
    return Table(Path(eff.source), {"symmetry": {"mirror_x": eff.mirror_x, "mirror_y": eff.mirror_y}}, {})


@pytest.mark.parametrize("mirror_x, mirror_y", [(True, True), (True, False), (False, True), (False, False)])
def test_fold_is_rcwa_tables_fold(efficiency, mirror_x, mirror_y):
    eff = dataclasses.replace(efficiency, mirror_x=mirror_x, mirror_y=mirror_y)
    phi = np.linspace(-400.0, 760.0, 2321)
    folded, flip = eff.fold(phi)
    expected = [_stored(eff).fold_azimuth(float(p)) for p in phi]
    assert np.allclose(folded, [e[0] for e in expected], atol=ROUND_OFF, rtol=0)
    assert np.array_equal(flip, [e[1] for e in expected])


def test_efficiency_reads_the_table_in_the_superstrate(efficiency):
    """At table nodes the value is the table's; between them, trilinear (scipy); the angle is
    the superstrate's (sin theta = sin_air / n(lambda)); azimuths beyond the stored range read
    the mirrored order; outside the table's wavelengths, zero."""
    eff = efficiency
    rng = np.random.default_rng(5)
    n_super = lambda lam: np.interp(lam, *eff.superstrate)  # noqa: E731
    assert 1.55 < n_super(550.0) < 1.62  # polycarbonate: the CD's superstrate
    for m in (1, -1, 2):
        i, j, k = (rng.integers(0, len(a), 20) for a in (eff.wavelengths_nm, eff.theta_deg[:-1], eff.phi_deg))
        lam, theta, phi = eff.wavelengths_nm[i], eff.theta_deg[j], eff.phi_deg[k]
        sin_air = n_super(lam) * np.sin(np.radians(theta))
        assert np.allclose(eff(m, lam, sin_air, phi), eff.values[i, j, k, eff.orders_m.index(m)], atol=ROUND_OFF, rtol=0)
        lam = rng.uniform(eff.wavelengths_nm[0], eff.wavelengths_nm[-1], 50)
        theta = rng.uniform(0.0, 60.0, 50)
        phi = rng.uniform(eff.phi_deg[0], eff.phi_deg[-1], 50)
        sin_air = n_super(lam) * np.sin(np.radians(theta))
        expected = _table_interpolator(eff, m)(np.stack([lam, theta, phi], axis=1))
        assert np.allclose(eff(m, lam, sin_air, phi), expected, atol=ROUND_OFF, rtol=0)
        # phi -> 180 - phi mirrors the grating vector: order m becomes -m (rcwa.symmetry)
        assert np.allclose(eff(-m, lam, sin_air, 180.0 - phi), expected, atol=ROUND_OFF, rtol=0)
    outside = np.array([eff.wavelengths_nm[0] - 5.0, eff.wavelengths_nm[-1] + 5.0])
    assert np.all(eff(1, outside, np.full(2, 0.3), np.zeros(2)) == 0.0)


def test_fresnel_transmission_is_born_and_wolfs():
    """Normal incidence: T = 4n / (n + 1)^2; otherwise Born & Wolf's forms (Sec. 1.5.2),
    R_s = sin^2(i - t) / sin^2(i + t), R_p = tan^2(i - t) / tan^2(i + t); at Brewster's angle
    the p wave passes whole; at grazing incidence nothing passes."""
    n = 1.59
    assert abs(prediction_efficiency.fresnel_transmission(np.array(1.0), n) - 4 * n / (n + 1) ** 2) < ROUND_OFF
    for i in np.radians([10.0, 35.0, 60.0, 80.0]):
        t = math.asin(math.sin(i) / n)
        rs = math.sin(i - t) ** 2 / math.sin(i + t) ** 2
        rp = math.tan(i - t) ** 2 / math.tan(i + t) ** 2
        assert abs(prediction_efficiency.fresnel_transmission(np.array(math.cos(i)), n) - (1 - (rs + rp) / 2)) < ROUND_OFF
    brewster = math.atan(n)
    rs = math.sin(brewster - math.asin(math.sin(brewster) / n)) ** 2 / math.sin(brewster + math.asin(math.sin(brewster) / n)) ** 2
    assert abs(prediction_efficiency.fresnel_transmission(np.array(math.cos(brewster)), n) - (1 - rs / 2)) < ROUND_OFF
    assert prediction_efficiency.fresnel_transmission(np.array(0.0), n) == 0.0


def test_flat_efficiency_without_a_top_gives_back_the_geometric_prediction(efficiency):
    """Without a top (no Fresnel) and with every order's efficiency the same constant, the
    weights are that constant everywhere: dividing by the order's mean leaves the geometric
    lit shares, and the order's mean efficiency is the constant."""
    spec = _scene(top=False)
    flat = dataclasses.replace(efficiency, values=np.full_like(efficiency.values, 0.3))
    weighted = prediction.predict(spec, weighting="efficiency", efficiency=flat)
    plain = prediction.predict(spec, weighting="geometric")
    assert weighted.orders == plain.orders
    assert np.allclose(weighted.lit, plain.lit, atol=ROUND_OFF, rtol=0)
    assert weighted.order_efficiency is not None and np.allclose(weighted.order_efficiency, 0.3, atol=ROUND_OFF, rtol=0)
    assert weighted.weighting == "efficiency" and plain.weighting == "geometric"


def _expected_lit(spec, eff: prediction_efficiency.Efficiency, pixel: np.ndarray, m: int) -> np.ndarray:
    """(3,) sum over the pixel's lit wavelengths of S_c E eta_m T_in T_out, from the definitions."""
    cd = prediction.cd_geometry(spec)
    camera = spec.camera.model
    wavelengths, lit = prediction.lit_table(spec, camera, pixel[None], m)
    weights = prediction.channel_weights(spec)[1]
    origin, ray = prediction.pixel_rays(camera, pixel[None])
    cos_camera = float(-(ray[0] @ cd.normal))
    stored = _stored(eff)
    total = np.zeros(3)
    for li in np.flatnonzero(lit[0]):
        lam = float(wavelengths[li])
        n_top = float(cd.top_index(np.array([lam]))[0])
        p = prediction.trace_to_grating(origin, ray, cd, n_top)[0][0]
        x_hat = (p - cd.center) / np.linalg.norm(p - cd.center)
        y_hat = np.cross(cd.normal, x_hat)
        toward_camera = -ray[0]
        k_out = np.array([toward_camera @ x_hat, toward_camera @ y_hat])  # tangential, in air (the top keeps it)
        k_in = np.array([k_out[0] - order_kx(0.0, m, cd.period_um * 1000.0, lam), k_out[1]])
        sin_air = float(np.hypot(*k_in))
        theta = math.degrees(math.asin(sin_air / float(np.interp(lam, *eff.superstrate))))
        phi, flip_m, _, _ = stored.fold_azimuth(math.degrees(math.atan2(k_in[1], k_in[0])))
        eta = float(_table_interpolator(eff, -m if flip_m else m)([[lam, theta, phi]])[0])
        fresnel = (prediction_efficiency.fresnel_transmission(np.array(cos_camera), n_top)
                   * prediction_efficiency.fresnel_transmission(np.array(math.sqrt(1.0 - sin_air**2)), n_top))
        total += weights[:, li] * eta * float(fresnel)
    return total


def test_a_lit_pixels_weight_is_the_efficiency_at_its_direction(efficiency):
    """Per channel, a pixel's lit share (one ray through its centre) is the sum over its lit
    wavelengths of S_c E eta_m(lambda, direction) T_in T_out, over the order's mean c_m."""
    spec = _scene(top=True)
    pred = prediction.predict(spec, supersample=1, efficiency=efficiency)
    assert pred.order_efficiency is not None
    checked = 0
    for k, m in enumerate(pred.orders):
        if abs(m) != 1:
            continue
        count = np.sum(np.isfinite(pred.lit_nm[k, 0]))
        ys, xs = np.nonzero(np.isfinite(pred.lit_nm[k, 0]))
        for idx in np.linspace(0, count - 1, PIXELS_CHECKED // 2).astype(int):
            pixel = np.array([xs[idx] + pred.x0, ys[idx] + pred.y0], float)
            expected = _expected_lit(spec, efficiency, pixel, m) / pred.order_efficiency[k]
            got = pred.lit[k, :, ys[idx], xs[idx]]
            assert np.allclose(got, expected, rtol=WEIGHT_TOLERANCE, atol=ROUND_OFF), (m, pixel, got, expected)
            checked += 1
    assert checked == PIXELS_CHECKED
    # the weighting matters here: the first orders' efficiency varies over the spectrum (0.06-0.4 in the draft
    # table), so order -1's shares (the view's widest band) move by a large fraction of the band's level
    plain = prediction.predict(spec, supersample=1, weighting="geometric")
    moved = np.abs(pred.lit[pred.orders.index(-1)] - plain.lit[plain.orders.index(-1)])
    assert moved.max() > MATTERS


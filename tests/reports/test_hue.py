"""reports/fringes/hue.py's hue crossings: the camera's hue as an equivalent wavelength.

The image here is made from the grating-equation prediction of cornell_cd_view2 with the
wavelength per pixel known: each pixel of order -1's band shows monochromatic light at
the middle of the wavelengths its centre ray receives, as the camera records it (S_c E at
that wavelength). The hue crossings found in it must lie where that wavelength map takes
the crossing's level.
"""

import cv2
import numpy as np
import pytest

from renderer.render import with_resolution
from renderer.scene import load_scene
from renderer.trace.prediction import channel_weights, light_white, predict
from reports.fringes import hue, polar
from reports.report import _sampled_prediction

RESOLUTION = (320, 240)
ORDER = -1  # spans the camera's whole range somewhere on cornell_cd_view2's CD
SCALE_ROUND_TRIP_NM = 1e-6  # the scale's own wavelengths come back exactly (interpolation at its nodes)
CROSSING_PX = 0.3  # median distance of a found crossing from where the known wavelength map takes its level
CROSSING_P90_PX = 1.0  # pixel mixing (bilinear samples of pixels about 17 nm apart here) and the map's 5 nm steps
MIN_CROSSINGS = 12  # 15 found in every seed; the count only guards that the median and p90 rest on enough crossings
# Noise (issue 23): the image's Gaussian noise of 1e-4 against a band of 40 is negligible; over 60 noise seeds
# the median is 0.1520 +- 0.0002 px, the 90th percentile 0.4441 +- 0.0002 px (> 700 and > 2000 SD inside the
# bounds: no false alarm from noise) and the count 15 in every seed: deterministic, but it sat on the bound itself,
# so one crossing whose quality flag moved with another machine's round-off failed the count. 12 leaves three.


@pytest.fixture(scope="module")
def setup():
    spec = with_resolution(load_scene("cornell_cd_view2"), RESOLUTION)
    wavelengths, weights = channel_weights(spec)
    white = light_white(spec)
    return spec, predict(spec), hue.hue_scale(wavelengths, weights, white), wavelengths, weights, white


def test_scale_inverts_monochromatic_light(setup):
    _spec, _pred, scale, wavelengths, weights, white = setup
    assert scale.wavelengths_nm[0] <= 450 and scale.wavelengths_nm[-1] >= 600  # the camera tells blue from red
    on_scale = np.isin(wavelengths, scale.wavelengths_nm)
    nm, saturation = scale.wavelength(weights.T[on_scale] * white[None] * 7.0)  # any brightness
    assert np.max(np.abs(nm - wavelengths[on_scale])) < SCALE_ROUND_TRIP_NM
    grey, grey_saturation = scale.wavelength(white[None] * 3.0)
    assert grey_saturation[0] < 1e-12  # the light itself has no hue


def _monochromatic_image(pred, wavelengths, weights, white, seed=0):
    i = pred.orders.index(ORDER)
    middle = pred.full(0.5 * (pred.lit_nm[i, 0] + pred.lit_nm[i, 1]), fill=np.nan)  # (H, W) nm, nan where unlit
    image = np.full(middle.shape + (3,), 0.02, np.float32) * white
    lit = np.isfinite(middle)
    balanced = np.stack([np.interp(middle[lit], wavelengths, weights[c]) for c in range(3)], axis=1)
    rgb = balanced / balanced.sum(axis=1, keepdims=True) * white  # one white-balanced brightness for every wavelength
    image[lit] += 40.0 * rgb.astype(np.float32)
    image += np.random.default_rng(seed).normal(0.0, 1e-4, image.shape).astype(np.float32)
    return image, middle


def test_hue_crossings_lie_where_the_wavelength_is_known(setup):
    spec, pred, scale, wavelengths, weights, white = setup
    image, middle = _monochromatic_image(pred, wavelengths, weights, white)
    gradient = np.hypot(*np.gradient(middle))  # nm per pixel
    distances = []
    circles, _radii = polar.standard_grids(pred.camera, pred.cd)  # hue crossings are measured along circles
    for grid in (circles,):
        for e in hue.find_hue_crossings(grid, _sampled_prediction(pred, grid), pred.orders, scale, image):
            if e.order != ORDER or e.quality != "ok":
                continue
            level = float(e.side.split()[0])
            at = np.array([[[e.x, e.y]]], np.float32)
            known = cv2.remap(middle.astype(np.float32), at[..., 0], at[..., 1], cv2.INTER_LINEAR)[0, 0]
            slope = cv2.remap(gradient.astype(np.float32), at[..., 0], at[..., 1], cv2.INTER_LINEAR)[0, 0]
            if np.isfinite(known) and slope > 0:
                distances.append(abs(known - level) / slope)
    assert len(distances) >= MIN_CROSSINGS
    assert np.median(distances) < CROSSING_PX
    assert np.percentile(distances, 90) < CROSSING_P90_PX


def test_no_hue_where_the_band_is_grey(setup):
    """A band of white light (every wavelength at once) has no equivalent wavelength: no crossing is ok."""
    spec, pred, scale, *_rest = setup
    i = pred.orders.index(ORDER)
    grey = pred.channel_image(ORDER).sum(axis=0)[..., None] * light_white(spec)[None, None]
    image = (0.02 * light_white(spec) + 5.0 * grey).astype(np.float32)
    for grid in polar.standard_grids(pred.camera, pred.cd):
        found = hue.find_hue_crossings(grid, _sampled_prediction(pred, grid), pred.orders, scale, image)
        assert not [e for e in found if e.order == pred.orders[i] and e.quality == "ok"]

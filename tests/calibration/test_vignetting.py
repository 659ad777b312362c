"""The vignetting fit (calibration.intrinsics.vignetting) on tiles of known falloff, and the synthetic lens's falloff.

The estimator's tests build a photo as s V(x) render with V the cos^p law of an ideal lens
(datasets_synthetic.sensor), the render a smooth positive field with Poisson-like noise,
some tiles made outliers (a caustic, a misplaced edge); the end-to-end test, that
``calibrate DATASET`` recovers a synthetic lens's falloff within 1 % at the corners, is in
tests/calibration/test_vignetting_dataset.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from calibration.intrinsics.vignetting import (
    CHANNELS,
    corner_x,
    falloff,
    fit_vignetting,
    relative_illumination,
    squared_field_tangent,
    wall_tiles,
)
from datasets_synthetic.sensor import SensorModel, checked_vignetting
from renderer.camera import CameraModel
from workbench.core.errors import UserInputError

CAMERA = CameraModel(640, 480, 880.0, 878.0, 322.0, 241.0)
POWERS = (3.8, 4.0, 4.4)


def _views(powers, seed: int, noise: float = 0.02, outliers: int = 20):
    """Two photos' (photo, render, mask): photo = s V render (1 + noise), ``outliers`` tiles doubled."""
    rng = np.random.default_rng(seed)
    truth = SensorModel(vignetting_power=powers).relative_illumination(CAMERA) if powers else np.ones((480, 640, 3))
    v, u = np.mgrid[0:480, 0:640]
    views = []
    for k, scale in enumerate((1.3, 0.8)):
        render = (0.4 + 0.2 * np.sin(u / 90.0 + k) * np.cos(v / 70.0))[..., None] * np.array([0.8, 1.0, 0.7])
        mask = (np.hypot(u - 320 - 60 * k, v - 240) > 40) & ((u + v + 50 * k) % 300 > 30)  # walls, cut by edges and an object
        photo = scale * truth * render * (1.0 + noise * rng.standard_normal(render.shape))
        for _ in range(outliers):
            r, c = rng.integers(0, 480 - 16), rng.integers(0, 640 - 16)
            photo[r:r + 16, c:c + 16] *= 2.0
        views.append((photo, render * (1.0 + 0.5 * noise * rng.standard_normal(render.shape)), mask))
    return {f"view{k}": wall_tiles(p, r, m, CAMERA) for k, (p, r, m) in enumerate(views)}, truth


def _truth_at_corners(truth: np.ndarray) -> dict[str, np.ndarray]:
    rows, cols = [0, 0, 479, 479], [0, 639, 0, 639]
    return {ch: truth[rows, cols, c] for c, ch in enumerate(CHANNELS)}


def test_the_falloff_of_a_cos4_lens_is_recovered_at_the_corners_within_its_std():
    """The ideal lens's cos^p falloff, (1 + x)^(-p/2), is smooth on x <= 0.21: a cubic in x
    follows it to 1e-4, so what is left is the noise, which the stated std must cover
    (4 std: 12 corner values, two-sided, well under a 1e-3 chance) and which is far below the
    issue's 1 % bar; 40 outlier tiles (a doubled brightness) must not move it."""
    tiles, truth = _views(POWERS, seed=1)
    record = fit_vignetting(tiles, CAMERA)
    expected = _truth_at_corners(truth)
    for ch in CHANNELS:
        error = np.asarray(record["corners"][ch]) - expected[ch]
        std = np.asarray(record["corners_std"][ch])
        assert np.all(np.abs(error) < 0.01), (ch, error)
        assert np.all(np.abs(error) < 4 * std), (ch, error, std)
        assert np.all(std < 0.005), std
    assert record["applied"], record["why"]
    falloff_map = relative_illumination(record, CAMERA)
    assert falloff_map is not None and falloff_map.shape == (480, 640, 3)
    assert abs(falloff_map[241, 322, 1] - 1.0) < 1e-4  # V = 1 on the axis, by the model's form


def test_the_stated_std_is_calibrated_over_noise_draws():
    """Over 12 draws of the noise the corners' errors over their std have an RMS between 0.5
    and 2 (a std that is honest to a factor of 2; the chi^2 of 12 x 4 x 3 correlated values
    keeps the RMS within about 0.3 of 1 when it is)."""
    z = []
    for seed in range(12):
        tiles, truth = _views(POWERS, seed=100 + seed, outliers=0)
        record = fit_vignetting(tiles, CAMERA)
        expected = _truth_at_corners(truth)
        for ch in CHANNELS:
            z += list((np.asarray(record["corners"][ch]) - expected[ch]) / np.asarray(record["corners_std"][ch]))
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert 0.5 < rms < 2.0, rms


def test_a_lens_without_vignetting_is_not_corrected():
    """No falloff in the photos: every corner's V is 1 within 3 of its std, so the stage must
    not apply a correction (applied False, and no map)."""
    tiles, _ = _views(None, seed=3)
    record = fit_vignetting(tiles, CAMERA)
    assert not record["applied"], record["why"]
    assert "not applied" in record["why"]
    assert relative_illumination(record, CAMERA) is None
    assert relative_illumination(None, CAMERA) is None


def test_the_model_is_one_on_the_axis_and_polynomial_in_the_squared_field_tangent():
    x = squared_field_tangent(CAMERA)
    assert x[241, 322] == pytest.approx(0.0, abs=1e-12)
    assert x[0, 0] == pytest.approx(corner_x(CAMERA)[0])
    assert x[0, 0] == pytest.approx((322 / 880.0) ** 2 + (241 / 878.0) ** 2)
    assert falloff(np.array([-0.5, 0.1, 0.0]), np.array([0.0, 0.2])) == pytest.approx([1.0, 1 - 0.1 + 0.004])


def test_the_synthetic_lens_follows_the_cos_p_law():
    """datasets_synthetic.sensor: V = cos^p(theta) with tan^2 theta = x (no distortion here)."""
    sensor = SensorModel(vignetting_power=POWERS)
    falloff_map = sensor.relative_illumination(CAMERA)
    x = squared_field_tangent(CAMERA)
    for c, p in enumerate(POWERS):
        assert np.allclose(falloff_map[..., c], (1.0 + x) ** (-p / 2), rtol=1e-9)
    assert np.all(SensorModel().relative_illumination(CAMERA) == 1.0)


@pytest.mark.parametrize("bad", [(4.0, 4.0), (4.0, -1.0, 4.0), (4.0, float("nan"), 4.0), ("a", 1, 2)])
def test_bad_vignetting_powers_are_refused_naming_the_option(bad):
    with pytest.raises(UserInputError, match="--vignetting"):
        checked_vignetting(bad)

"""DNG files read back by rawpy, and the sensor noise model's statistics.

* rawpy opens the DNG; raw values read back bit-exact; black level, white level, CFA
  pattern and as-shot white balance as written; exposure time, ISO, make, model and the
  colour matrix as written (read with tifffile, an independent TIFF parser: LibRaw does
  not expose them all).
* Noise: over repeated captures of a flat field, each pixel's mean and variance agree
  with the model (EMVA 1288 linear model) within their statistical error: 5 standard
  errors of the mean, and of the variance (sqrt(2/(n-1)) relative for Gaussian-like
  noise), averaged over pixels. Noise allowed (issue 23): shot and read noise, from the
  model under test (Poisson at 900-3000 electrons: Gaussian to a skewness under 0.04; the
  1/12 DN^2 of quantisation is 4e-5 of the variance). Comparisons: 4 CFA colours x (mean,
  variance), each a mean over 256 pixels x 200 frames: Gaussian, Z_STAT = 5.5 standard
  errors, 8 x 2 Q(5.5) = 3e-7 false alarms per run (5, as before: 4.6e-6). Smallest
  defects caught: a 0.1 % error in the mean level (5.5 x 0.19 DN at ~1200 DN), a 3.5 %
  error in the variance (5.5 x 0.63 %), e.g. shot noise drawn for 3.5 % too many electrons.
* Clipping: exactly the pixels whose value would exceed the white level are clipped.
"""

import numpy as np
import pytest
import rawpy
import tifffile

from datasets_synthetic.dng import DngMetadata, write_dng
from datasets_synthetic.sensor import SensorModel

Z_STAT = 5.5  # standard errors, on 8 Gaussian statistics: 8 x 2 Q(5.5) = 3e-7 false alarms per run


def _pattern(r) -> str:
    """The 2x2 CFA pattern as letters (LibRaw names the second green G as well: 'RGBG')."""
    desc = r.color_desc.decode()
    return "".join(desc[i] for i in r.raw_pattern.ravel())


def test_dng_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    raw = rng.integers(0, 16383, (48, 64)).astype(np.uint16)
    meta = DngMetadata(cfa_pattern="RGGB", black_level=600, white_level=16383, exposure_time_s=1 / 250, iso=400,
                       as_shot_neutral=(0.5, 1.0, 0.625),
                       color_matrix=(0.9, -0.3, -0.1, -0.4, 1.2, 0.2, -0.05, 0.15, 0.6))
    path = write_dng(tmp_path / "a.dng", raw, meta)
    with rawpy.imread(str(path)) as r:
        assert np.array_equal(r.raw_image_visible, raw)
        assert r.black_level_per_channel == [600] * 4 and r.white_level == 16383
        assert _pattern(r) == "RGGB"
        assert np.allclose(r.camera_whitebalance[:3], [2.0, 1.0, 1.6], rtol=1e-6)
    with tifffile.TiffFile(path) as t:
        tags = t.pages[0].tags
        assert tags[33434].value == (1, 250) and tags[34855].value == 400
        assert tags[271].value == "Workbench" and tags[272].value == "Synthetic RGGB"
        cm = np.array(tags[50721].value, dtype=float).reshape(9, 2)
        assert np.allclose(cm[:, 0] / cm[:, 1], meta.color_matrix)
        assert tuple(bytes(tags[33422].value)) == (0, 1, 1, 2)  # CFAPattern is stored as BYTEs


@pytest.mark.parametrize("pattern", ["RGGB", "BGGR", "GRBG"])
def test_cfa_patterns_read_back(tmp_path, pattern):
    raw = np.zeros((40, 40), np.uint16)
    path = write_dng(tmp_path / "p.dng", raw, DngMetadata(cfa_pattern=pattern))
    with rawpy.imread(str(path)) as r:
        assert _pattern(r) == pattern


def test_noise_matches_the_model():
    sensor = SensorModel(electrons_per_unit=3000.0, gain=0.8, read_noise_e=4.0)
    flat = np.ones((32, 32, 3)) * np.array([0.5, 1.0, 0.3])
    rng = np.random.default_rng(42)
    frames = np.stack([sensor.capture(flat, 1.0, rng) for _ in range(200)]).astype(float)
    mean_model, var_model = sensor.expected_dn(flat, 1.0)
    n = frames.shape[0]
    mean, var = frames.mean(axis=0), frames.var(axis=0, ddof=1)
    # Averaged over the pixels of each CFA colour: the tests' statistical errors.
    for dy in (0, 1):
        for dx in (0, 1):
            m, mm = mean[dy::2, dx::2], mean_model[dy::2, dx::2]
            v, vm = var[dy::2, dx::2], var_model[dy::2, dx::2]
            pixels = m.size
            se_mean = np.sqrt(vm.mean() / n / pixels)
            assert abs(m.mean() - mm.mean()) < Z_STAT * se_mean
            se_var = vm.mean() * np.sqrt(2.0 / (n - 1) / pixels)
            assert abs(v.mean() - vm.mean()) < Z_STAT * se_var


def test_clipping_is_exactly_above_the_white_level():
    sensor = SensorModel(electrons_per_unit=1.0, gain=1.0, read_noise_e=0.0, black_level=0, bits=12)
    rgb = np.zeros((8, 8, 3))
    rgb[..., 0] = rgb[..., 1] = rgb[..., 2] = np.linspace(3000, 5000, 64).reshape(8, 8)
    raw = sensor.capture(rgb, 1.0, np.random.default_rng(0))
    # No read noise: values are Poisson around mu; those over 4095 are exactly the clipped ones.
    rng = np.random.default_rng(0)
    unclipped = rng.poisson(sensor.expected_electrons(rgb, 1.0))
    assert np.array_equal(raw == 4095, unclipped >= 4095)
    assert np.array_equal(raw[unclipped < 4095], unclipped[unclipped < 4095])

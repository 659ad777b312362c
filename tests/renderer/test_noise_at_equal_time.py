"""Noise at equal time on the real scene (renderer/bench_noise.py, small settings).

Asserted, as the issue asks, only that improved mode's error on the CD at equal wall time
is not higher than paper mode's, in both measures (relative RMS error and relative MSE,
the reference's own noise removed). ``make bench`` prints the ratio at larger settings
(measured 3.8x in relative RMS error, 45x in relative MSE at 20 s per mode, 640 x 480);
most of it is paper mode's bias: with four wavelengths per ray its Delta test keeps the
diffracted light on about one of them, so the CD comes out at about 45 % of its
brightness.
"""

import pytest


@pytest.mark.slow
def test_improved_is_not_noisier_at_equal_time(mitsuba_variant):
    from benchmarks.bench_noise import noise_at_equal_time

    r = noise_at_equal_time(resolution=(320, 240), budget_s=2.0, reference_spp=2048)
    paper, improved = r["modes"]["paper"]["at_budget"], r["modes"]["improved"]["at_budget"]
    print(r)
    assert r["cd_pixels"] > 500
    assert improved["relative_rms_error"] <= paper["relative_rms_error"]
    assert improved["relative_mse"] <= paper["relative_mse"]

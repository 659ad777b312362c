"""Noise at equal cost on the real scene (benchmarks/bench_noise.py, small settings).

Asserted: at equal samples per pixel, improved mode's error on cornell_cd's CD is at most
half of paper mode's (GOAL_RATIO = 2, the issue's goal) in the relative RMS error, and at
most a quarter (GOAL_RATIO^2, the same goal for a squared error) in the relative MSE; the
references' own noise is removed from both.

Why samples, not seconds (issue 23): a test that measures "equal time" with the clock
fails on a busy machine. The sample count is a deterministic cost, and the modes' samples
cost about the same: ``make bench`` (bench_noise, timed) measured 524 paper and 537 improved
spp in the same 2.7 s here, so equal samples favour paper mode by 2-3 % and the assertion
is, if anything, conservative. The timed comparison stays in the benchmark.

Settings: 160 x 120 (the CD, propped toward the camera since issue 15, covers 520 pixels),
SPP = 512 per mode, two 8192-spp improved references. Paper mode's error is mostly bias
there, which more samples do not remove: with four wavelengths per ray its Delta test keeps
the diffracted light on about one of them, so the CD comes out at about 45 % of its
brightness. Measured with these settings: paper 1.64 relative RMS error, improved 0.36 (4.5x;
relative MSE 0.214 against 0.0175, 12x).

Noise allowed. Improved mode's error is Monte Carlo noise; its relative RMS error is
estimated over the CD's ~520 pixels, so the estimate itself spreads by about
sqrt(2 / 520) = 6 % between seeds or CPUs, and the reference noise subtracted from it is
smaller still (2 x 8192 spp against 512). The measured 4.5x sits 2.2x above the bar of 2:
a false alarm would need the error estimate to be 2.2x its expectation, about 20 of its
standard deviations, with a false-alarm rate per run far below 1e-9. The assertion still
catches a real loss: improved mode at 2.2x its noise, as if it had a fifth of its samples.
"""

import pytest

GOAL_RATIO = 2.0
RESOLUTION = (160, 120)
SPP = 512
REFERENCE_SPP = 8192


@pytest.mark.slow
def test_improved_has_at_most_half_the_error_at_equal_samples(mitsuba_variant):
    from benchmarks.bench_noise import noise_at_equal_samples

    r = noise_at_equal_samples(resolution=RESOLUTION, spp=SPP, reference_spp=REFERENCE_SPP)
    paper, improved = r["modes"]["paper"], r["modes"]["improved"]
    print(r)
    assert r["cd_pixels"] > 200
    assert paper["spp"] == improved["spp"] == SPP
    assert paper["relative_rms_error"] >= GOAL_RATIO * improved["relative_rms_error"]
    assert paper["relative_mse"] >= GOAL_RATIO**2 * improved["relative_mse"]

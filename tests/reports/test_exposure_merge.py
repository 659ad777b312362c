"""reports/compare/exposure_merge.py: a photo's clipped highlights filled from darker frames of its view.

The frames are made here from one known irradiance image (a smooth ramp with a bright band,
as a CD's first order is against the walls), exposed at known ratios, clipped at 1 and given
shot-like noise: the merge must give back the irradiance where the photo clipped, with the
exposure ratios measured from the images, and refuse (or leave out) frames of another view.

Noise allowed (issue 23): the frames' noise only, from a stated model (multiplicative,
Gaussian, NOISE per sample: shot-like noise at a few thousand photo-electrons; no read
noise, no render: the irradiance is exact). A filled sample is one frame's sample times a
measured ratio, so its relative error is that frame's noise (sigma = NOISE; measured 1.000
NOISE over 200 realisations) plus the ratio's error (measured 4e-5 to 8e-5: a median over
thousands of pixels). Comparisons: ~21,000 filled samples (pixels x channels) against
VALUE_TOL = 7 NOISE: 21,339 x 2 Q(7) = 5.5e-8 per run (5 NOISE, as before, gave about 1 %:
1 of 200 realisations failed). The ratios: RATIO_TOL is 60 of their standard errors: no
false alarm. Smallest defects caught: a ratio off by 0.5 % (RATIO_TOL), a filled value off
by 3 % (a wrong frame's scaling, a pixel taken from its neighbour on the band's slope).
"""

import numpy as np
import pytest

from reports.compare.exposure_merge import MAX_RELATIVE_SPREAD, merge_highlights
from reports.compare.images import Photo
from workbench.core.errors import UserInputError

SHAPE = (120, 160)
NOISE = 0.004  # relative noise of a frame's pixel (a few thousand photo-electrons)
RATIO_TOL = 0.005  # the measured ratio over thousands of pixels: noise / sqrt(n) is far below this
VALUE_TOL = 7 * NOISE  # the largest of ~21,000 filled samples, each NOISE (one frame's) x a ratio good to 1e-4:
                       # 21,339 x 2 Q(7) = 5.5e-8 false alarms per run


def _scene() -> np.ndarray:
    """Irradiance in the photo's units: textured walls 0.1-0.6 (something to register the frames on, as a room
    has), and a band 6-40x brighter across the middle."""
    import cv2

    y, x = np.mgrid[0:SHAPE[0], 0:SHAPE[1]]
    texture = cv2.GaussianBlur(np.random.default_rng(99).standard_normal(SHAPE), (0, 0), 3.0)
    base = (0.1 + 0.5 * x / SHAPE[1]) * (1 + 0.3 * texture / texture.std())
    band = np.exp(-(((y - 60) / 12.0) ** 2)) * (6.0 + 34.0 * x / SHAPE[1])
    rgb = np.stack([base + band, 0.9 * base + 0.8 * band, 0.8 * base + 0.6 * band], axis=2)
    return rgb.astype(np.float32)


def _frame(irradiance: np.ndarray, exposure: float, seed: int, name: str) -> Photo:
    rng = np.random.default_rng(seed)
    values = irradiance * exposure * (1 + NOISE * rng.standard_normal(irradiance.shape))
    clipped = np.any(values >= 1.0, axis=2)
    values = np.minimum(values, 1.0).astype(np.float32)
    return Photo(values, clipped, name, "linear", clip_level=1.0 if clipped.any() else None,
                 decoding={"exposure_time_s": 0.01 * exposure})


def test_clipped_band_is_filled_with_the_irradiance():
    truth = _scene()
    photo = _frame(truth, 1.0, 0, "ev+0")
    frames = [_frame(truth, 2.0 ** ev, 10 + i, f"ev{ev:+d}") for i, ev in enumerate((-1, -2, -4, -6, 1))]
    assert photo.clipped.mean() > 0.1  # the band clips the photo
    merged, used, skipped = merge_highlights(photo, frames)
    assert [u.path for u in used] == ["ev-1", "ev-2", "ev-4", "ev-6"]  # brighter to darker
    assert skipped == {"ev+1": "not darker than the photo"}
    for record, ev in zip(used, (-1, -2, -4, -6), strict=True):
        assert record.ratio == pytest.approx(2.0 ** -ev, rel=RATIO_TOL)
        assert record.exif_ratio == pytest.approx(2.0 ** -ev, rel=1e-12)
    assert not merged.clipped.any()  # the band peaks at 40 x: ev-6 (1/64) holds it
    filled = photo.clipped
    assert np.max(np.abs(merged.rgb[filled] / truth[filled] - 1)) < VALUE_TOL
    np.testing.assert_array_equal(merged.rgb[~filled], photo.rgb[~filled])  # the photo's own pixels stay
    assert merged.clip_level == pytest.approx(64.0, rel=RATIO_TOL)


def test_pixels_clipped_in_every_frame_stay_clipped():
    truth = _scene()
    photo = _frame(truth, 1.0, 0, "ev+0")
    merged, used, _ = merge_highlights(photo, [_frame(truth, 0.25, 1, "ev-2")])
    assert merged.clipped.any() and merged.clipped.sum() < photo.clipped.sum()
    assert merged.clip_level == pytest.approx(4.0, rel=RATIO_TOL)
    assert np.all(merged.clipped <= photo.clipped)


def test_measured_ratio_wins_over_a_wrong_exif_time():
    """Shutters are nominal: a frame labelled 1/4 but really 0.3 of the photo's exposure is scaled by 1 / 0.3."""
    truth = _scene()
    photo = _frame(truth, 1.0, 0, "ev+0")
    frame = _frame(truth, 0.3, 1, "ev-2")
    frame.decoding["exposure_time_s"] = 0.01 * 0.25
    merged, used, _ = merge_highlights(photo, [frame])
    assert used[0].ratio == pytest.approx(1 / 0.3, rel=RATIO_TOL) and used[0].exif_ratio == pytest.approx(4.0)


def test_a_frame_of_another_view_is_refused_or_left_out():
    truth = _scene()
    photo = _frame(truth, 1.0, 0, "ev+0")
    other = _frame(np.ascontiguousarray(np.roll(truth, 12, axis=1)), 0.25, 1, "another view")  # taken 12 px aside
    with pytest.raises(UserInputError) as caught:
        merge_highlights(photo, [other])
    assert "another view" in str(caught.value) and "--bracket" in str(caught.value)
    merged, used, skipped = merge_highlights(photo, [other], strict=False)
    assert not used and "shifted by 12.0 px" in skipped["another view"]
    np.testing.assert_array_equal(merged.rgb, photo.rgb)


def test_frames_of_another_size_or_kind_are_refused():
    truth = _scene()
    photo = _frame(truth, 1.0, 0, "ev+0")
    small = _frame(truth[:60, :80], 0.25, 1, "small")
    with pytest.raises(UserInputError, match="size"):
        merge_highlights(photo, [small])
    raw_like = _frame(truth, 0.25, 2, "raw")
    raw_like.kind = "raw"
    with pytest.raises(UserInputError, match="raw"):
        merge_highlights(photo, [raw_like])


def test_without_overlap_or_exif_the_frame_is_refused():
    truth = _scene()
    photo = _frame(truth, 1.0, 0, "ev+0")
    dark = _frame(truth, 1 / 128, 1, "ev-7")  # the walls under the level a ratio needs, the band clipped in the photo
    dark.decoding.pop("exposure_time_s")
    with pytest.raises(UserInputError, match="exposure times"):
        merge_highlights(photo, [dark])


def test_spread_bar_separates_noise_from_another_view():
    """The bar on the relative spread sits well above what noise gives (a few NOISE) and below a moved view."""
    assert 5 * NOISE < MAX_RELATIVE_SPREAD < 0.5

"""Raw sensor layouts other than the 2 x 2 Bayer array (calibration.raw.layout).

Each synthetic raw is written by datasets_synthetic.dng and read back by LibRaw:
* a linear DNG (LinearRaw, 3 samples per pixel: the layout a Nikon scanner NEF has, which
  ended in rawpy's "RAW image is not flat" traceback) and a monochrome DNG decode to
  exactly (raw - black) / (white - black) per sample (float32 rounding: 1e-6), no
  demosaicing, saturated exactly where a pixel's own sample reached the white level;
* an X-Trans (6 x 6) mosaic of a smooth scene decodes to linear camera RGB within 1 % of
  the truth away from the edges (the issue's bar), through our normalised convolution
  (``linear``) and through LibRaw's three-pass Markesteijn (``ahd``);
* the saturation mask follows each demosaicing: one raw sample of each of the 36 pattern
  phases set to the white level, every pixel whose developed value moves by more than one
  16-bit code (1 / 65535) lies inside the mask, and for ours the mask is not wider than
  the change (its reach, 1 pixel, is the 3 x 3 footprint's);
* the sidecar records layout, demosaicing and why.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from calibration.pose.photo import mosaic_like, read_photo
from calibration.raw.decode import decode, decode_to_exr
from datasets_synthetic.dng import DngMetadata, write_dng
from workbench.cli import main
from workbench.core.errors import UserInputError

XTRANS = "GGRGGB" "GGBGGR" "BRGRBG" "GGBGGR" "GGRGGB" "RBGBRG"   # Fujifilm's 6 x 6, row-major
BLACK, WHITE = 512, 16383
ONE_CODE = 1.0 / 65535.0
EDGE = 8          # pixels left out at the borders (the issue: "away from edges"; Markesteijn's border is 8)
REL_TOL = 0.01    # the bar for X-Trans decoded to linear camera RGB


def _scene(h: int, w: int) -> np.ndarray:
    """Smooth linear camera RGB: ramps in x and y, a slow wave in blue (0.2-0.5, 0.4-0.6, 0.25-0.35)."""
    y, x = np.mgrid[0:h, 0:w] / np.array([h, w])[:, None, None]
    return np.stack([0.2 + 0.3 * x, 0.4 + 0.2 * y, 0.3 + 0.05 * np.sin(2 * np.pi * x)], axis=-1)


def _mosaic(rgb: np.ndarray, pattern: str) -> np.ndarray:
    side = int(len(pattern) ** 0.5)
    h, w = rgb.shape[:2]
    channel = np.array(["RGB".index(c) for c in pattern]).reshape(side, side)
    channel = np.tile(channel, (h // side + 1, w // side + 1))[:h, :w]
    return np.take_along_axis(rgb, channel[..., None], axis=2)[..., 0]


def _raw(values: np.ndarray) -> np.ndarray:
    return np.round(BLACK + np.clip(values, 0, 1) * (WHITE - BLACK)).astype(np.uint16)


def _meta(pattern: str) -> DngMetadata:
    return DngMetadata(cfa_pattern=pattern, black_level=BLACK, white_level=WHITE, model="Layout")


def test_linear_dng_three_samples_read_as_they_are(tmp_path, capsys):
    rng = np.random.default_rng(7)
    samples = rng.integers(0, WHITE + 1, (40, 56, 3)).astype(np.uint16)
    samples[3, 5, 1] = WHITE                       # one saturated sample
    path = write_dng(tmp_path / "linear.dng", samples, _meta(""))
    decoded = decode(path)
    expected = np.clip((samples - float(BLACK)) / (WHITE - BLACK), 0, None)
    np.testing.assert_allclose(decoded.pixels, expected, rtol=0, atol=1e-6)
    assert np.array_equal(decoded.saturated, np.any(samples >= WHITE, axis=2)) and decoded.saturated[3, 5]
    info = decoded.info
    assert (info.cfa, info.demosaic, info.channels) == (None, "none", ["R", "G", "B"])
    assert "3 samples per pixel" in str(info.layout) and "as they are" in str(info.demosaic_reason)
    assert info.black_level == [512.0] * 3 and info.white_level == WHITE
    assert main(["decode", str(path), "--out", str(tmp_path / "l.exr"), "--json"]) == 0   # no traceback: exit 0
    printed = json.loads(capsys.readouterr().out)
    sidecar = json.loads((tmp_path / "l.json").read_text())
    assert printed["demosaic"] == sidecar["demosaic"] == "none" and sidecar["layout"] == info.layout


def test_monochrome_dng_one_channel(tmp_path):
    samples = np.random.default_rng(8).integers(0, WHITE + 1, (48, 40)).astype(np.uint16)
    path = write_dng(tmp_path / "mono.dng", samples, _meta(""))
    decoded = decode(path)
    assert decoded.pixels.shape == (48, 40, 1) and decoded.info.channels == ["Y"]
    np.testing.assert_allclose(decoded.pixels[..., 0], np.clip((samples - float(BLACK)) / (WHITE - BLACK), 0, None),
                               rtol=0, atol=1e-6)
    assert np.array_equal(decoded.saturated, samples >= WHITE) and str(decoded.info.layout).startswith("monochrome")
    photo = read_photo(path)                       # the pose fit's reader: grey repeated into three channels
    assert photo.rgb.shape == (48, 40, 3) and np.array_equal(photo.rgb[..., 0], photo.rgb[..., 2])


@pytest.fixture(scope="module")
def xtrans(tmp_path_factory) -> tuple[Path, np.ndarray, np.ndarray]:
    """An X-Trans raw of the smooth scene, 516 x 528 (LibRaw's Markesteijn refuses images under ~512 pixels)."""
    folder = tmp_path_factory.mktemp("xtrans")
    truth = _scene(516, 528)
    raw = _raw(_mosaic(truth, XTRANS))
    return write_dng(folder / "xtrans.dng", raw, _meta(XTRANS)), raw, truth


@pytest.mark.parametrize("demosaic", ["linear", "ahd"])
def test_xtrans_decodes_to_linear_rgb_within_one_percent(xtrans, demosaic):
    path, _, truth = xtrans
    decoded = decode(path, demosaic=demosaic)
    info = decoded.info
    assert info.cfa == XTRANS and info.layout == "X-Trans 6 x 6" and info.demosaic == demosaic
    inner = (slice(EDGE, -EDGE), slice(EDGE, -EDGE))
    relative = np.abs(decoded.pixels[inner] / truth[inner] - 1.0)
    print(f"{demosaic}: max relative error {relative.max():.2e}, median {np.median(relative):.2e}")
    assert relative.max() < REL_TOL


@pytest.mark.parametrize("demosaic", ["linear", "ahd"])
def test_xtrans_saturation_mask_follows_the_demosaicing(tmp_path, xtrans, demosaic):
    path, raw, _ = xtrans
    clipped = raw.copy()
    spots = [(100 + 40 * (k // 6) + k // 6, 100 + 40 * (k % 6) + k % 6) for k in range(36)]   # every phase once
    for y, x in spots:
        clipped[y, x] = WHITE
    bright = write_dng(tmp_path / "clipped.dng", clipped, _meta(XTRANS))
    before, after = decode(path, demosaic=demosaic), decode(bright, demosaic=demosaic)
    moved = np.abs(after.pixels - before.pixels).max(axis=2) > ONE_CODE
    assert moved.sum() >= 36 and not before.saturated.any()
    assert np.all(after.saturated[moved]), "a pixel changed by a saturated sample is outside the mask"
    if demosaic == "linear":   # the mask is as tight as the change: its reach is 1 pixel, as the 3 x 3 footprint's
        ys, xs = np.nonzero(moved)
        reach = np.min(np.maximum(np.abs(ys[:, None] - np.array(spots)[None, :, 0]),
                                  np.abs(xs[:, None] - np.array(spots)[None, :, 1])), axis=1)
        assert reach.max() == 1 and after.saturated.sum() == 36 * 9


def test_xtrans_small_image_and_the_renders_mosaic(tmp_path):
    """Markesteijn through LibRaw on a small X-Trans raw fails inside LibRaw: refused, naming --demosaic; ours
    works, and calibration.pose.photo.mosaic_like takes a render through the same array and demosaicing (so photo and
    render blur alike): the decode of a raw equals mosaic_like of its normalised truth, to one raw code."""
    truth = _scene(96, 120)
    raw = _raw(_mosaic(truth, XTRANS))
    path = write_dng(tmp_path / "small.dng", raw, _meta(XTRANS))
    with pytest.raises(UserInputError, match="--demosaic"):
        decode(path, demosaic="ppg")
    decoded = decode(path)
    assert decoded.info.cfa == XTRANS
    # the raw's rounding moves each sample by at most half a raw code, so each weighted mean by no more
    np.testing.assert_allclose(mosaic_like(truth.astype(np.float32), decoded.info.cfa), decoded.pixels,
                               rtol=0, atol=0.5 / (WHITE - BLACK) + 1e-6)
    record = decode_to_exr(path, tmp_path / "small.exr")
    sidecar = json.loads((tmp_path / "small.json").read_text())
    assert sidecar == json.loads(json.dumps(record)) and sidecar["layout"] == "X-Trans 6 x 6"
    assert "normalised convolution" in sidecar["demosaic_reason"] and sidecar["settings"]["demosaic"] == "linear"

"""Four-colour filter arrays (CMYG, RGBW) through LibRaw (calibration.raw.layout).

Each raw is a DNG written by datasets_synthetic.dng (CFAPattern of four colours and
CFAPlaneColor) of a smooth four-channel scene, read back by LibRaw:
* its four camera channels, named by filter colour (LibRaw itself calls every DNG's
  channels "GMCY"), decode within 1 % of the truth away from the edges (the issue's bar)
  through LibRaw's linear and its VNG; measured on CMYG: 4.7e-4 and 5.2e-3 at most, the
  linear one the raw's own rounding (half a DN of 15871) and the scene's curvature, VNG's
  its gradient weighting, both far below the bar;
* the EXR names the channels C, M, Y, G and its ``saturated`` channel is the mask (before,
  three names for four channels put "saturated" on the fourth colour);
* a DNG without CFAPlaneColor gets LibRaw's own guess of the channel order (Y, C, M, G);
* the saturation mask follows each demosaicing: a saturated sample of each of the four
  pattern phases moves pixels at most 1 away through linear, 2 through VNG (measured), all
  of them inside the mask.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import tifffile

from calibration.raw.decode import decode, decode_to_exr
from datasets_synthetic.dng import DngMetadata, write_dng

BLACK, WHITE = 512, 16383
EDGE = 8          # pixels left out at the borders ("away from edges", as tests/calibration/test_raw_layouts.py)
REL_TOL = 0.01    # the bar for X-Trans and four-colour raws decoded to linear camera values
ONE_CODE = 1.0 / 65535.0
SHAPE = (64, 96)


def _scene() -> np.ndarray:
    """Four smooth planes (plane k: the k-th colour of the pattern's CFAPlaneColor), 0.2 to 0.6."""
    y, x = np.mgrid[0:SHAPE[0], 0:SHAPE[1]] / np.array(SHAPE)[:, None, None]
    return np.stack([0.2 + 0.3 * x, 0.4 + 0.2 * y, 0.3 + 0.05 * np.sin(2 * np.pi * x), 0.25 + 0.15 * x * y], axis=-1)


def _raw(pattern: str, truth: np.ndarray) -> np.ndarray:
    planes = "".join(dict.fromkeys(pattern))
    phase = np.array([planes.index(c) for c in pattern]).reshape(2, 2)
    channel = np.tile(phase, (SHAPE[0] // 2, SHAPE[1] // 2))
    mosaic = np.take_along_axis(truth, channel[..., None], axis=2)[..., 0]
    return np.round(BLACK + mosaic * (WHITE - BLACK)).astype(np.uint16)


def _meta(pattern: str) -> DngMetadata:
    return DngMetadata(cfa_pattern=pattern, black_level=BLACK, white_level=WHITE, model="Four colours")


@pytest.mark.parametrize("pattern", ["CMYG", "RGBW"])
@pytest.mark.parametrize("demosaic", ["linear", "vng"])
def test_four_colour_dng_decodes_to_its_camera_channels(pattern: str, demosaic: str, tmp_path: Path) -> None:
    truth = _scene()
    path = write_dng(tmp_path / "four.dng", _raw(pattern, truth), _meta(pattern))
    decoded = decode(path, demosaic=demosaic)
    info = decoded.info
    assert info.channels == list(pattern) and info.cfa == pattern and info.layout == f"4-colour 2 x 2 ({pattern})"
    assert info.demosaic == demosaic and "4-colour filter array" in str(info.demosaic_reason)
    inner = (slice(EDGE, -EDGE), slice(EDGE, -EDGE))
    error = np.abs(decoded.pixels[inner] - truth[inner]) / truth[inner]
    assert error.max() < REL_TOL, error.reshape(-1, 4).max(axis=0)
    assert not decoded.saturated.any()


def test_the_exr_names_four_channels_and_the_mask(tmp_path: Path) -> None:
    import OpenImageIO as oiio

    truth = _scene()
    raw = _raw("CMYG", truth)
    raw[20, 30] = WHITE
    path = write_dng(tmp_path / "four.dng", raw, _meta("CMYG"))
    record = decode_to_exr(path, tmp_path / "four.exr")
    image = oiio.ImageBuf(str(tmp_path / "four.exr"))
    names = list(image.spec().channelnames)
    pixels = image.get_pixels(oiio.FLOAT)
    assert pixels is not None, image.geterror()
    assert sorted(names) == sorted(["C", "M", "Y", "G", "saturated"]) and record["channels"] == ["C", "M", "Y", "G"]
    mask = pixels[..., names.index("saturated")]
    assert set(np.unique(mask)) == {0.0, 1.0} and mask[20, 30] == 1.0 and mask.sum() == 9   # linear: 3 x 3
    inner = (slice(EDGE, -EDGE), slice(EDGE, -EDGE))
    green = pixels[..., names.index("G")][inner]
    assert np.all(np.abs(green - truth[inner][..., 3]) / truth[inner][..., 3] < REL_TOL)


def test_a_dng_without_plane_colours_gets_libraws_own_order(tmp_path: Path) -> None:
    """Without CFAPlaneColor, LibRaw orders a green-cyan-magenta-yellow array's channels Y, C, M, G (its
    parse_tiff_ifd); the names follow, so the channel called Y holds the yellow samples."""
    truth = _scene()
    whole = write_dng(tmp_path / "whole.dng", _raw("CMYG", truth), _meta("CMYG"))
    with tifffile.TiffFile(whole) as tif:
        page = tif.pages.first
        tags = [(t.code, t.dtype, t.count, t.value, True) for t in page.tags
                if (t.code >= 33421 or t.code in (271, 272)) and t.code != 50710]
        samples = page.asarray()
    bare = tmp_path / "bare.dng"
    tifffile.imwrite(bare, samples, photometric=32803, extratags=tags, subfiletype=0, metadata=None)
    decoded = decode(bare)
    assert decoded.info.channels == ["Y", "C", "M", "G"] and decoded.info.cfa == "CMYG"
    inner = (slice(EDGE, -EDGE), slice(EDGE, -EDGE))
    for name, plane in zip("CMYG", range(4), strict=True):
        got = decoded.pixels[inner][..., decoded.info.channels.index(name)]
        assert np.all(np.abs(got - truth[inner][..., plane]) / truth[inner][..., plane] < REL_TOL), name


@pytest.mark.parametrize(("demosaic", "reach"), [("linear", 1), ("vng", 2)])
def test_the_saturation_mask_follows_libraws_demosaicing(demosaic: str, reach: int, tmp_path: Path) -> None:
    truth = _scene()
    raw = _raw("CMYG", truth)
    spots = [(20, 30), (20, 61), (41, 30), (41, 61)]      # one sample of each of the four pattern phases
    hot = raw.copy()
    for y, x in spots:
        hot[y, x] = WHITE
    base = decode(write_dng(tmp_path / "base.dng", raw, _meta("CMYG")), demosaic=demosaic)
    saturated = decode(write_dng(tmp_path / "hot.dng", hot, _meta("CMYG")), demosaic=demosaic)
    moved = np.any(np.abs(saturated.pixels - base.pixels) > ONE_CODE, axis=2)
    ys, xs = np.nonzero(moved)
    distance = np.min([np.maximum(np.abs(ys - y), np.abs(xs - x)) for y, x in spots], axis=0)
    assert distance.max() == reach                         # the measured reach the footprint is made from
    assert not np.any(moved & ~saturated.saturated)        # every pixel a saturated sample moves is masked


@pytest.mark.parametrize("reader", ["calibration", "reports"])
def test_the_photo_readers_refuse_a_four_colour_raw_naming_its_channels(reader: str, tmp_path: Path) -> None:
    """calibrate pose and report compare the photo with the RGB scene camera: a four-colour raw
    is refused with the file and its channels named (before, its first three planes, C, M, Y,
    were taken as R, G, B without a word); a Bayer raw of the same writer still reads as RGB."""
    from calibration.pose.photo import read_photo as calibration_photo
    from reports.compare.images import read_photo as report_photo
    from workbench.core.errors import UserInputError

    read = calibration_photo if reader == "calibration" else report_photo
    four = write_dng(tmp_path / "cmyg.dng", _raw("CMYG", _scene()), _meta("CMYG"))
    with pytest.raises(UserInputError) as info:
        read(four)
    assert info.value.got == str(four) and "C, M, Y, G" in str(info.value), str(info.value)
    rgb = _scene()[..., :3]
    bayer = write_dng(tmp_path / "rggb.dng", _raw("RGGB", rgb), DngMetadata(cfa_pattern="RGGB", black_level=BLACK,
                                                                            white_level=WHITE, model="Bayer"))
    assert read(bayer).rgb.shape == (*SHAPE, 3)

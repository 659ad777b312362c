"""`workbench decode FILE --out X.exr`, then X.exr as a photo (issue 45 item 5).

The EXR the decode writes (channels R, G, B, saturated; the decode in its header) is read
back by reports.compare.images.read_photo, by calibration.pose.photo.read_photo and by
`workbench report --photo` as the raw file it came from: the same pixels (bit for bit:
float32 written losslessly, float32 read), the same saturation mask, colour pattern, clip
level and decode record. An EXR of another layout is refused in one line naming the file and
its channels.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from calibration.pose import photo as pose_photo
from calibration.raw.decode import decode
from reports.compare import images
from tests.calibration.test_decode import _capture
from workbench.core.errors import UserInputError

REAL = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"
COLORCHART = REAL / "colorchart.dng"
needs_real = pytest.mark.skipif(not COLORCHART.is_file(), reason=f"the real raw is not at {COLORCHART}")
SIZE = (160, 120)   # the synthetic photo: small, so that a whole report takes seconds


def _decode_command(source: Path, out: Path, capsys) -> None:
    from workbench.cli import main

    assert main(["decode", str(source), "--out", str(out)]) == 0, capsys.readouterr().err
    capsys.readouterr()


def _same_photo(exr_photo: images.Photo, raw_photo: images.Photo) -> None:
    """The EXR read as its raw file is: pixels, mask, mosaic, clip level, kind and decode record."""
    np.testing.assert_array_equal(exr_photo.rgb, raw_photo.rgb)
    np.testing.assert_array_equal(exr_photo.clipped, raw_photo.clipped)
    np.testing.assert_array_equal(exr_photo.channel, raw_photo.channel)
    assert exr_photo.kind == raw_photo.kind == "raw" and exr_photo.clip_level == raw_photo.clip_level
    assert exr_photo.decoding == raw_photo.decoding   # levels, CFA, EXIF, demosaicing restored from the header


@needs_real
def test_real_raw_through_decode_reads_back_as_the_raw(tmp_path, capsys):
    exr = tmp_path / "colorchart.exr"
    _decode_command(COLORCHART, exr, capsys)
    from_exr, from_raw = images.read_photo(exr), images.read_photo(COLORCHART)
    _same_photo(from_exr, from_raw)
    assert from_exr.decoding["cfa"] == "RGGB" and from_exr.decoding["black_level"] == [2056.0] * 4
    assert from_exr.decoding["white_level"] == 15000.0 and from_exr.decoding["linear"] is True
    # A calibration's response curve is for codes: a linear EXR ignores it (the report passes it to every photo).
    with_curve = images.read_photo(exr, {"points": [[0.0, 0.0], [1.0, 1.0]]})
    np.testing.assert_array_equal(with_curve.rgb, from_raw.rgb)
    # Calibration's photo reader: the same pixels, mask and pattern.
    pose_read = pose_photo.read_photo(exr)
    np.testing.assert_array_equal(pose_read.rgb, decode(COLORCHART).pixels)
    assert pose_read.cfa == "RGGB" and pose_read.linear and pose_read.saturated.shape == pose_read.rgb.shape[:2]
    # ... and with calibrate DATASET's inverse response (for codes), which a linear EXR ignores too
    curved = pose_photo.read_photo(exr, lambda v: v**2.2)
    np.testing.assert_array_equal(curved.rgb, pose_read.rgb)


def test_saturation_mask_is_carried(tmp_path, capsys):
    """A synthetic raw exposed so that its brightest patches clip (about a third of the pixels)."""
    dng, _ = _capture(tmp_path, "clipped.dng", 0.5, size=(SIZE[1], SIZE[0]))
    exr = tmp_path / "clipped.exr"
    _decode_command(dng, exr, capsys)
    from_exr, from_raw = images.read_photo(exr), images.read_photo(dng)
    assert 0.05 < from_raw.clipped.mean() < 0.95   # some pixels clip, not all: the mask carries information
    _same_photo(from_exr, from_raw)
    assert from_exr.clip_level == 1.0
    assert pose_photo.read_photo(exr).exposure_time_s == pytest.approx(0.5)   # EXIF from the header


def _write_exr(path: Path, pixels: np.ndarray, names: list[str], header: str | None = None) -> Path:
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], oiio.FLOAT)
    spec.channelnames = tuple(names)
    if header is not None:
        spec.attribute("workbench:decode", header)
    out = oiio.ImageOutput.create(str(path))
    assert out is not None and out.open(str(path), spec)
    out.write_image(np.ascontiguousarray(pixels, np.float32))
    out.close()
    return path


def test_channels_are_picked_by_name(tmp_path):
    """B, G, R, A stored in another order read back as R, G, B; alpha left out; no mask: none clipped."""
    rgb = np.random.default_rng(0).random((8, 10, 3)).astype(np.float32)
    alpha = np.ones((8, 10, 1), np.float32)
    path = _write_exr(tmp_path / "bgra.exr", np.concatenate([rgb[..., ::-1], alpha], axis=2), ["B", "G", "R", "A"])
    decoded = decode(path)
    np.testing.assert_array_equal(decoded.pixels, rgb)
    assert decoded.info.channels == ["R", "G", "B"] and not decoded.saturated.any() and decoded.info.linear


def test_unsupported_layouts_are_refused_in_one_line(tmp_path, capsys):
    from workbench.cli import main

    pixels = np.zeros((4, 5, 4), np.float32)
    extra = _write_exr(tmp_path / "extra.exr", pixels, ["R", "G", "B", "Z"])
    with pytest.raises(UserInputError, match="unsupported channel layout") as error:
        images.read_photo(extra)
    assert str(extra) in str(error.value) and "['R', 'G', 'B', 'Z']" in str(error.value)
    code = main(["decode", str(extra), "--out", str(tmp_path / "out.exr")])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and "'Z'" in err
    # A header naming channels the file does not hold, and a header that is not the decode's record.
    header = json.dumps({"channels": ["C", "M", "Y", "G"], "linear": True})
    mismatched = _write_exr(tmp_path / "cmyg.exr", pixels, ["R", "G", "B", "saturated"], header)
    with pytest.raises(UserInputError, match=r"unsupported channel layout.*C, M, Y, G"):
        decode(mismatched)
    broken = _write_exr(tmp_path / "broken.exr", pixels, ["R", "G", "B", "saturated"], "not json")
    with pytest.raises(UserInputError, match="decode header"):
        decode(broken)


def test_a_decode_of_codes_stays_non_linear_until_a_curve_is_given(tmp_path, capsys):
    """A JPEG decoded without a response holds codes in [0, 1] (header: linear false): as a photo
    it needs the calibration's curve, which it then goes through."""
    from PIL import Image

    codes = np.random.default_rng(1).integers(0, 256, (12, 16, 3)).astype(np.uint8)
    jpeg = tmp_path / "codes.png"
    Image.fromarray(codes, "RGB").save(jpeg)
    exr = tmp_path / "codes.exr"
    _decode_command(jpeg, exr, capsys)
    with pytest.raises(UserInputError, match="not linear"):
        images.read_photo(exr)
    squared = {"points": [[float(x), float(np.sqrt(x))] for x in np.linspace(0.0, 1.0, 257)]}   # value = sqrt(E)
    photo = images.read_photo(exr, squared)
    np.testing.assert_allclose(photo.rgb, (codes / 255.0) ** 2, atol=2e-3)   # PCHIP of a 257-point table
    assert photo.kind == "linear" and photo.channel is None


@pytest.mark.slow
def test_report_takes_the_decoded_exr(tmp_path, capsys):
    """The chain of commands: decode a raw, report on its EXR against a synthetic (flat) render.
    The report runs (exit 0), reads the photo as raw and takes its clipped pixels from the mask."""
    from renderer.render import with_resolution
    from renderer.scene import load_scene
    from workbench.cli import main

    dng, _ = _capture(tmp_path, "photo.dng", 0.5, size=(SIZE[1], SIZE[0]))
    exr = tmp_path / "photo.exr"
    _decode_command(dng, exr, capsys)
    camera = with_resolution(load_scene("cornell_cd_view2"), SIZE).camera.model
    calibration = tmp_path / "calibration.json"
    calibration.write_text(json.dumps({"scene": "cornell_cd_view2", "camera": {
        "width": camera.width, "height": camera.height, "fx": camera.fx, "fy": camera.fy, "cx": camera.cx,
        "cy": camera.cy, "dist": list(camera.dist), "world_to_camera": {exr.name: camera.world_to_camera.tolist()}}}))
    render = _write_exr(tmp_path / "render.exr", np.full((SIZE[1], SIZE[0], 3), 0.3, np.float32), ["R", "G", "B"])
    code = main(["report", "--photo", str(exr), "--render", str(render), "--calibration", str(calibration),
                 "--scene", "cornell_cd_view2", "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    clipped = decode(dng).saturated
    assert report["photo_kind"] == "raw" and report["photo_decoding"]["cfa"] == "RGGB"
    assert report["photo_clipped_pixels"] == int(clipped.sum()) > 0

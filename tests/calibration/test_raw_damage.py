"""Damaged or unsupported raw files are refused, never decoded into a silent black image.

The damaged files are made from whole, valid raws: a DNG our synthetic writer writes
(datasets_synthetic.dng) and the real Canon DNG (../shared/data/real/colorchart.dng,
skipped when missing), then cut short, their samples zeroed, or their Compression tag
set to a codec LibRaw lacks. Each case must be a UserInputError whose one-line message
names the file and says what is wrong; through the CLI, exit 2 with no traceback, in
``workbench decode`` and ``workbench calibrate intrinsics``. The readers of the other
commands (calibration.pose.photo for pose and ``calibrate DATASET``, reports.compare.images for
``report``) go through the same decode and give the same message. Two controls show the
checks do not refuse what they must not: a whole file, and a dark frame with a small
black level whose noise reaches 0 at 14 % of the samples (isolated zeros, not blocks).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
import rawpy
import tifffile

from calibration.raw.checks import MAX_ZERO_BLOCK_FRACTION, zero_block_fraction
from calibration.raw.decode import decode
from datasets_synthetic.dng import DngMetadata, write_dng
from workbench.cli import main
from workbench.core.errors import UserInputError

REAL = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"
COLORCHART = REAL / "colorchart.dng"
needs_real = pytest.mark.skipif(not COLORCHART.is_file(), reason=f"the real raw is not at {COLORCHART}")
META = DngMetadata(black_level=512, white_level=16383, make="Workbench", model="Damage")


def _whole(tmp_path: Path, name: str = "whole.dng", shape: tuple[int, int] = (64, 96)) -> Path:
    """A valid synthetic DNG: noise around mid-grey, black 512, white 16383."""
    raw = np.random.default_rng(4).normal(6000, 300, shape).clip(0, 16383).astype(np.uint16)
    return write_dng(tmp_path / name, raw, META)


def _image_start(path: Path) -> tuple[int, tifffile.TiffTag, str]:
    with tifffile.TiffFile(path) as tif:
        page = tif.pages.first
        return min(page.dataoffsets), page.tags["Compression"], tif.byteorder


def _with_compression(path: Path, out: Path, code: int) -> Path:
    """A copy of ``path`` whose raw IFD's Compression tag says ``code`` (its samples left as they are)."""
    _, tag, order = _image_start(path)
    data = bytearray(path.read_bytes())
    data[tag.valueoffset:tag.valueoffset + 2] = struct.pack(order + "H", code)
    out.write_bytes(bytes(data))
    return out


def _refused(path: Path, *words: str) -> str:
    with pytest.raises(UserInputError) as caught:
        decode(path)
    message = str(caught.value)
    assert path.name in message and "\n" not in message, message
    for word in words:
        assert word in message, message
    return message


def test_truncated_dng_is_refused_before_libraw(tmp_path):
    """Cut at the first byte of the image data (a header that claims the full size, as the 13 kB DNG did) and
    halfway through it: the strips run past the end of the file, which the message says with the missing share."""
    whole = _whole(tmp_path)
    start, _, _ = _image_start(whole)
    data = whole.read_bytes()
    for cut, missing in ((start, 100.0), ((start + len(data)) // 2, 50.0)):
        bad = tmp_path / f"cut{cut}.dng"
        bad.write_bytes(data[:cut])
        message = _refused(bad, "truncated", "96 x 64")
        share = float(message.split("(")[1].split(" %")[0])
        assert share == pytest.approx(missing, abs=0.5)   # 0.5 %: the header's share of the file


def test_undecodable_samples_are_refused_not_black(tmp_path):
    """A DNG whose Compression says lossless JPEG over plain samples: LibRaw reads it without an error (its image
    buffer left as allocated: zeros, or old memory), so the decode must refuse it, naming the tile that is not a JPEG
    stream; and one with 0.2 % of its samples present (the RW2 case), the rest zero below the black level."""
    whole = _whole(tmp_path)
    fake = _with_compression(whole, tmp_path / "fake_ljpeg.dng", 7)
    with rawpy.imread(str(fake)) as libraw:
        assert libraw.raw_image_visible.shape == (64, 96)   # LibRaw's own answer: an image, no error
    _refused(fake, "damaged image data", "strip or tile 1 of 1", "not a JPEG stream", "lossless JPEG")
    raw = np.zeros((64, 96), np.uint16)
    raw.flat[:int(0.002 * raw.size) + 1] = 6000          # the first 0.2 % of the samples, the rest never written
    sparse = write_dng(tmp_path / "sparse.dng", raw, META)
    message = _refused(sparse, "damaged image data", "black level 512")
    assert "99." in message                              # the share of the image in all-zero blocks
    zeros = write_dng(tmp_path / "zeros.dng", np.zeros((64, 96), np.uint16), META)
    _refused(zeros, "every raw sample is 0")


def test_unsupported_compression_is_named(tmp_path):
    """GoPro VC-5 (LibRaw needs the GPR SDK) and Deflate (needs zlib): refused, naming the compression."""
    whole = _whole(tmp_path)
    _refused(_with_compression(whole, tmp_path / "gopro.dng", 9), "GoPro VC-5", "TIFF Compression 9")
    deflated = tmp_path / "deflate.dng"
    samples = tifffile.imread(whole)
    tags = [(t.code, t.dtype, t.count, t.value, True) for t in tifffile.TiffFile(whole).pages.first.tags
            if t.code >= 33421 or t.code in (271, 272)]
    tifffile.imwrite(deflated, samples, photometric=32803, extratags=tags, subfiletype=0, metadata=None,
                     compression="zlib")
    assert _image_start(deflated)[1].value == 8  # really Deflate-compressed
    try:
        decode(deflated)
    except UserInputError as exc:
        assert "Deflate" in str(exc) and deflated.name in str(exc)
    else:  # a LibRaw built with zlib decodes it: then it must be the samples themselves
        np.testing.assert_array_equal(decode(deflated).pixels, decode(whole).pixels)


def test_whole_files_and_isolated_zeros_pass(tmp_path):
    """Controls: a whole file decodes; a dark frame at black level 4 with read noise 3.7 DN has 14 % of its
    samples at 0 (clipped noise), isolated, so no 4 x 4 block is all zero and it is not refused."""
    assert decode(_whole(tmp_path)).pixels.shape == (64, 96, 3)
    dark = np.random.default_rng(5).normal(4, 3.7, (128, 160)).round().clip(0, None).astype(np.uint16)
    assert 0.1 < np.mean(dark == 0) < 0.2 and zero_block_fraction(dark) <= MAX_ZERO_BLOCK_FRACTION
    path = write_dng(tmp_path / "dark.dng", dark, DngMetadata(black_level=4, white_level=16383))
    assert decode(path).info.black_level == [4.0] * 4


@needs_real
def test_real_dng_cut_short_or_zeroed_is_refused(tmp_path):
    """The real Canon DNG cut to its first 13 kB, and with all but the first 5 % of its image bytes zeroed (the
    first 2 % are the masked rows above the visible area)."""
    head = tmp_path / "head.dng"
    head.write_bytes(COLORCHART.read_bytes()[:13_000])
    _refused(head, "truncated", "1888 x 1182")
    start, _, _ = _image_start(COLORCHART)
    data = bytearray(COLORCHART.read_bytes())
    keep = start + int(0.05 * (len(data) - start))
    data[keep:] = bytes(len(data) - keep)
    zeroed = tmp_path / "zeroed.dng"
    zeroed.write_bytes(bytes(data))
    _refused(zeroed, "damaged image data", "black level 2056")


def _board_views(tmp_path: Path) -> list[Path]:
    """Three copies of a rendered chessboard view (PNG), enough views to get past the count check."""
    import cv2

    board = np.kron((np.indices((7, 10)).sum(axis=0) % 2).astype(np.uint8) * 255, np.ones((30, 30), np.uint8))
    image = np.full((300, 400), 128, np.uint8)
    image[45:255, 50:350] = board
    paths = []
    for n in range(3):
        paths.append(tmp_path / f"view{n}.png")
        cv2.imwrite(str(paths[-1]), image)
    return paths


def test_commands_exit_2_naming_the_damaged_photo(tmp_path, capsys):
    """``workbench decode`` and ``workbench calibrate intrinsics`` with a damaged raw among the views: exit 2, one
    line naming the file, nothing written."""
    whole = _whole(tmp_path)
    bad = tmp_path / "bad.dng"
    bad.write_bytes(whole.read_bytes()[:_image_start(whole)[0] + 100])
    sparse = tmp_path / "sparse.dng"
    raw = np.zeros((64, 96), np.uint16)
    raw[:1] = 6000
    write_dng(sparse, raw, META)
    for damaged, words in ((bad, "truncated"), (sparse, "damaged image data")):
        code = main(["decode", str(damaged), "--out", str(tmp_path / "o.exr")])
        err = capsys.readouterr().err.strip()
        assert code == 2 and err.startswith("error: ") and damaged.name in err and words in err, err
        assert "Traceback" not in err and len(err.splitlines()) == 1 and not (tmp_path / "o.exr").exists()
        views = [*_board_views(tmp_path), damaged]
        code = main(["calibrate", "intrinsics", *map(str, views), "--board", "9x6", "--square-mm", "25",
                     "--out", str(tmp_path / "i.json")])
        err = capsys.readouterr().err.strip()
        assert code == 2 and damaged.name in err and words in err and "Traceback" not in err, err
        assert not (tmp_path / "i.json").exists()


def test_pose_and_report_readers_give_the_same_refusal(tmp_path):
    """calibration.pose.photo.read_photo (pose, calibrate DATASET, verify's calibration step) and
    reports.compare.images.read_photo (report) decode through calibration.raw.decode.decode: the same damaged
    file, the same message."""
    from calibration.pose.photo import read_photo as pose_read
    from reports.compare.images import read_photo as report_read

    raw = np.zeros((64, 96), np.uint16)
    raw[:1] = 6000
    sparse = write_dng(tmp_path / "sparse.dng", raw, META)
    messages = set()
    for reader in (decode, pose_read, report_read):
        with pytest.raises(UserInputError) as caught:
            reader(sparse)
        messages.add(str(caught.value))
    assert len(messages) == 1 and "damaged image data" in messages.pop()

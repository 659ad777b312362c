"""Damaged or unsupported raw files, refused before they become a silent black image.

LibRaw (through rawpy) refuses many broken files itself, but not all: a DNG whose strips
or tiles are missing, or whose lossless-JPEG tiles do not start with a JPEG header, is
"decoded" without an error (LibRaw's lossless_dng_load_raw stops at the first tile whose
ljpeg_start fails and leaves the rest of the buffer as allocated: zeros, or whatever the
memory held before, seen in tests as values above the white level). Three
checks, each a one-line UserInputError naming the file:

* ``check_container`` (DNG, before LibRaw): every raw image IFD's strips or tiles
  (StripOffsets/StripByteCounts or TileOffsets/TileByteCounts, [TIFF 6.0, Sec. 3 and 15];
  the raw IFDs are those with NewSubFileType 0 and PhotometricInterpretation CFA 32803 or
  LinearRaw 34892, [DNG 1.4, Ch. 3]) must end inside the file (a file cut short fails
  it), and JPEG-compressed ones must start with a JPEG stream.
* ``check_samples`` (every raw, after LibRaw): the raw samples may not be all zero, and
  where the black level is above zero, no more than MAX_ZERO_BLOCK_FRACTION of the 4 x 4
  sample blocks may be entirely zero. A live sensor's sample sits at the black level plus
  signal plus read noise, so reading exactly 0 needs noise a full black level below it:
  isolated zeros happen in deep shadows of cameras with a small black level, but sixteen
  neighbours all at zero (probability p**16 for a per-sample probability p) do not; missing
  data (a truncated stream, damaged tiles, a file with 0.2 % of its pixels present) is
  zero in whole rows or tiles.
* ``check_raw_file``: both checks on a file before anything else reads it (``workbench
  verify``'s up-front check of every raw in a dataset), returning its visible size: the
  same refusals, word for word, as the decode's.
* ``libraw_failure``: when LibRaw refuses a DNG whose raw image is compressed, the message
  names the compression (TIFF Compression tag), e.g. GoPro's VC-5, which LibRaw reads only
  when built with the GoPro GPR SDK, or Deflate without zlib.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from workbench.core.errors import UserInputError

CFA_PHOTOMETRIC = 32803
LINEAR_RAW_PHOTOMETRIC = 34892
COMPRESSION_NAMES = {1: "no", 7: "lossless JPEG", 8: "Deflate", 9: "GoPro VC-5", 34892: "lossy JPEG",
                     52546: "JPEG XL"}
JPEG_COMPRESSIONS = (7, 34892)
BLOCK = 4                          # side of the sample blocks tested for missing data
MAX_ZERO_BLOCK_FRACTION = 1e-3     # all-zero 4 x 4 blocks tolerated (dead-pixel clusters), as a fraction of blocks


@dataclass(frozen=True)
class RawIfd:
    """One raw image IFD of a DNG: its size, compression and where its image data ends."""

    width: int
    height: int
    compression: int
    offsets: tuple[int, ...]   # where its strips or tiles start
    data_end: int              # one past the last byte of its strips or tiles

    @property
    def data_size(self) -> int:
        return self.data_end - min(self.offsets, default=self.data_end)


def compression_name(code: int) -> str:
    return f"{COMPRESSION_NAMES.get(code, 'unknown')} compression (TIFF Compression {code})"


def dng_raw_ifds(path: Path) -> list[RawIfd]:
    """The raw image IFDs of a DNG (IFD 0 and its SubIFDs), read with tifffile; [] when tifffile cannot parse it."""
    import tifffile  # deferred: start-up time

    quiet = logging.getLogger("tifffile")
    level = quiet.level
    quiet.setLevel(logging.CRITICAL)   # a damaged file makes tifffile log; the checks below say what is wrong
    try:
        with tifffile.TiffFile(path) as tif:
            pages = [page for top in tif.pages for page in (top, *(getattr(top, "pages", None) or []))]
            return [_raw_ifd(page) for page in pages if _is_raw_page(page)]
    except Exception:  # noqa: BLE001 - an unparseable header is LibRaw's to judge
        return []
    finally:
        quiet.setLevel(level)


def _is_raw_page(page) -> bool:
    subfile = page.tags.get("NewSubfileType")
    return (subfile is None or int(subfile.value) == 0) and int(page.photometric) in (CFA_PHOTOMETRIC,
                                                                                      LINEAR_RAW_PHOTOMETRIC)


def _raw_ifd(page) -> RawIfd:
    ends = [int(o) + int(n) for o, n in zip(page.dataoffsets, page.databytecounts, strict=False)]
    return RawIfd(width=int(page.imagewidth), height=int(page.imagelength), compression=int(page.compression),
                  offsets=tuple(int(o) for o in page.dataoffsets), data_end=max(ends, default=0))


def check_container(path: Path) -> list[RawIfd]:
    """Refuse a DNG whose raw image data runs past the end of the file, or whose JPEG-compressed strips or tiles
    do not start with a JPEG SOI marker (FF D8, [ITU T.81, B.1.1.3]; LibRaw's ljpeg_start gives up there and leaves
    the image buffer as allocated: zeros or old memory, without an error); returns its raw IFDs ([] for others)."""
    if path.suffix.lower() != ".dng":
        return []
    ifds = dng_raw_ifds(path)
    size = path.stat().st_size
    for ifd in ifds:
        if ifd.data_end > size:
            missing = min(ifd.data_end - size, ifd.data_size) / max(ifd.data_size, 1)
            raise UserInputError(
                f"truncated: its {ifd.width} x {ifd.height} raw image's data needs {ifd.data_end} bytes but the file "
                f"has {size} ({100.0 * missing:.1f} % of the image data is missing)", file=path,
                expected="the complete file")
        if ifd.compression in JPEG_COMPRESSIONS:
            _check_jpeg_starts(path, ifd)
    return ifds


def _check_jpeg_starts(path: Path, ifd: RawIfd) -> None:
    with open(path, "rb") as handle:
        for n, offset in enumerate(ifd.offsets):
            handle.seek(offset)
            if handle.read(2) != b"\xff\xd8":
                raise UserInputError(
                    f"damaged image data: strip or tile {n + 1} of {len(ifd.offsets)} of its {ifd.width} x "
                    f"{ifd.height} raw image is not a JPEG stream (no SOI marker at byte {offset}), though its "
                    f"{compression_name(ifd.compression)} says it is", file=path, expected="an undamaged raw file")


def check_samples(path: Path, samples: np.ndarray, black_level: float) -> None:
    """Refuse raw samples (H, W) or (H, W, C) that are all zero, or, with a black level above zero, hold more than
    MAX_ZERO_BLOCK_FRACTION of all-zero 4 x 4 blocks (see the module docstring)."""
    flat = samples.max(axis=2) if samples.ndim == 3 else samples
    if not flat.any():
        raise UserInputError(f"every raw sample is 0 (black level {black_level:g}): the file holds no image data",
                             file=path, expected="an undamaged raw file")
    if black_level <= 0:
        return
    fraction = zero_block_fraction(flat)
    if fraction > MAX_ZERO_BLOCK_FRACTION:
        raise UserInputError(
            f"damaged image data: {100.0 * fraction:.1f} % of its raw samples lie in all-zero {BLOCK} x {BLOCK} "
            f"blocks, below the black level {black_level:g} (missing or corrupted data)", file=path,
            expected=f"at most {100.0 * MAX_ZERO_BLOCK_FRACTION:g} % (a complete raw file)")


def zero_block_fraction(flat: np.ndarray) -> float:
    """The fraction of the aligned BLOCK x BLOCK blocks of ``flat`` (H, W) whose samples are all zero."""
    h, w = (flat.shape[0] // BLOCK) * BLOCK, (flat.shape[1] // BLOCK) * BLOCK
    if h == 0 or w == 0:
        return float(not flat.any())
    blocks = flat[:h, :w].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK).max(axis=(1, 3))
    return float(np.mean(blocks == 0))


def libraw_failure(message: str, ifds: list[RawIfd]) -> str:
    """LibRaw's refusal in words, naming the raw image's compression where it is one LibRaw may lack."""
    import rawpy  # deferred: start-up time

    compressed = sorted({ifd.compression for ifd in ifds} - {1, 7})
    if compressed:
        version = ".".join(map(str, rawpy.libraw_version))
        return (f"its raw image uses {compression_name(compressed[0])}, which this LibRaw ({version}) does not "
                f"decode (LibRaw: {message})")
    return f"cannot be decoded as a raw photograph ({message})"


def used_black_levels(raw) -> list[float]:
    """The black levels of the channels the open rawpy ``raw``'s samples use (its ``num_colors`` first for a
    stacked or monochrome raw, all four CFA entries otherwise): the lowest is check_samples' black level."""
    import rawpy  # deferred: start-up time

    black = [float(b) for b in raw.black_level_per_channel]
    return black[:max(1, int(raw.num_colors))] if raw.raw_type != rawpy.RawType.Flat or raw.num_colors == 1 else black


def libraw_message(exc: Exception) -> str:
    """A LibRawError's text (rawpy gives bytes or str)."""
    text = exc.args[0] if exc.args else exc
    return text.decode(errors="replace") if isinstance(text, bytes) else str(text)


def check_raw_file(path: Path) -> tuple[int, int]:
    """(width, height) LibRaw sees of the raw file ``path``, after check_container and check_samples: the decode's
    refusals, word for word (LibRaw's own refusal through libraw_failure), without demosaicing."""
    import rawpy  # deferred: start-up time

    ifds = check_container(path)
    try:
        with rawpy.imread(str(path)) as raw:
            check_samples(path, raw.raw_image_visible, min(used_black_levels(raw)))
            return int(raw.sizes.width), int(raw.sizes.height)
    except rawpy.LibRawError as exc:
        raise UserInputError(libraw_failure(libraw_message(exc), ifds), file=path,
                             expected="a complete raw file LibRaw reads (DNG, NEF, CR2, ARW, ...)") from None

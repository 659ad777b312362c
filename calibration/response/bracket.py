"""Reading an exposure bracket for calibration.response.calibrate: the images' codes, their local
levels and which values are usable, and the exposure times (``--times`` or each file's
EXIF: calibration.raw.decode.read_exif, LibRaw's shutter time for raw formats without TIFF
tags); for a raw bracket, the raw values normalised by the black and white levels.

Units: images enter as integer codes (8 or 16 bits) and are normalised to values
y = code / (2^bits - 1) in [0, 1]; raw values as (count - black) / (white - black); times
in seconds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration.raw.decode import is_raw, read_exif
from workbench.core.errors import UserInputError

IMAGE_SUFFIXES = frozenset({".jpg", ".jpeg", ".png", ".tif", ".tiff"})

# Which values are used. A value whose neighbourhood mean reaches SATURATED may be clipped,
# or a demosaicked or compressed neighbour of a clipped one, and so may every value within
# SATURATION_RADIUS_PX of one; below DARK_CODES (of 255) it may be clipped at black.
SATURATED = 0.98
SATURATION_RADIUS_PX = 2
DARK_CODES = 2
USABLE_FRACTION_MIN = 1e-3   # below this fraction of usable values an image is "all black" or "all saturated"
MAX_PIXELS = 1_000_000       # larger images are read at a stride (the curve needs values, not detail)
# Raw brackets: a raw value is used where its neighbourhood lies between these fractions of
# the black-to-white range.
RAW_USABLE = (0.02, 0.9)


@dataclass(frozen=True)
class Bracket:
    """Images of one view at several exposure times, as normalised values.

    ``codes``: (n, h, w, c) uint8/uint16 pixel values; ``bits``: 8 or 16 (y = code /
    (2^bits - 1)); ``levels``: (n, h, w, c) float32 local means of y (5 x 5), which decide
    what is usable and how much it weighs without looking at a pixel's own noise (a value
    kept because its noise pushed it below a threshold would bias the fit); ``usable``:
    (n, h, w, c) bool, False where a value is clipped, dark, saturated or near a saturated
    pixel; ``times_s``: (n,) seconds.
    """

    codes: np.ndarray
    levels: np.ndarray
    usable: np.ndarray
    times_s: np.ndarray
    bits: int
    files: tuple[str, ...]
    channels: tuple[str, ...]
    stride: int = 1


@dataclass(frozen=True)
class RawBracket:
    """A raw bracket as values of every pixel (at a stride for large sensors) over its n
    exposures: ``values`` (pixels, n), normalised raw values; ``usable`` (pixels, n), 1.0
    where the value's neighbourhood lies within RAW_USABLE of the black-to-white range,
    else 0.0; ``times_s`` (n,) seconds."""

    values: np.ndarray
    usable: np.ndarray
    times_s: np.ndarray


def _exposure_time(path: Path) -> float | None:
    """The file's EXIF ExposureTime (calibration.raw.decode.read_exif), else, for raw formats
    whose tags it cannot read, LibRaw's shutter time."""
    seconds = read_exif(path)["exposure_time_s"]
    if seconds is None and is_raw(path):
        import rawpy  # deferred: start-up time

        try:
            with rawpy.imread(str(path)) as raw:
                shutter = float(raw.other.shutter_speed)
        except (rawpy.LibRawError, OSError) as error:
            raise UserInputError(f"cannot read the raw file ({error})", file=path) from None
        seconds = shutter if math.isfinite(shutter) and shutter > 0 else None
    return seconds


def exposure_times(paths: Sequence[str | Path], times_s: Sequence[float] | None = None) -> np.ndarray:
    """The bracket's exposure times: ``times_s`` (from ``--times``) when given, else each
    file's EXIF; a clear error names the first file without one."""
    if times_s is not None:
        times = np.asarray(times_s, dtype=float)
        if times.shape != (len(paths),):
            raise UserInputError("one exposure time per image is needed", field="--times",
                                 expected=f"{len(paths)} times (one per image)", got=len(times))
        if not np.all(np.isfinite(times) & (times > 0)):
            raise UserInputError("exposure times must be positive seconds", field="--times", got=list(times_s))
        return times
    found = []
    for path in map(Path, paths):
        seconds = _exposure_time(path)
        if seconds is None:
            raise UserInputError("no exposure time in the file's EXIF", file=path, field="ExposureTime",
                                 expected="EXIF ExposureTime, or the bracket's times with --times T,...")
        found.append(seconds)
    return np.asarray(found)


def check_paths(paths: Sequence[str | Path]) -> list[Path]:
    """The bracket's files as paths: at least two, each an existing raw file or JPEG, PNG or
    TIFF, not raw and developed mixed; a UserInputError names the first that is not."""
    if len(paths) < 2:
        raise UserInputError("a response curve needs an exposure bracket", field="IMAGE",
                             expected="at least 2 images of one view at different exposure times", got=len(paths))
    checked = [Path(p) for p in paths]
    for path in checked:
        if not path.is_file():
            raise UserInputError("no such file", file=path)
        if not (is_raw(path) or path.suffix.lower() in IMAGE_SUFFIXES):
            raise UserInputError("unknown image type", file=path,
                                 expected="a raw file LibRaw reads (DNG, NEF, CR2, ...) or a JPEG, PNG or TIFF",
                                 got=path.suffix)
    if len({is_raw(p) for p in checked}) > 1:
        raise UserInputError("a bracket mixes raw and developed images", field="IMAGE",
                             expected="all raw (checked for linearity) or all JPEG/PNG/TIFF (response fitted)",
                             got=[p.name for p in checked])
    return checked


def _check_times(paths: list[Path], times: np.ndarray) -> None:
    if len(np.unique(times)) < 2:
        raise UserInputError("every image has the same exposure time", field="exposure times",
                             expected="at least two different times", got=[float(t) for t in times])


def _read_codes(path: Path) -> np.ndarray:
    """An 8/16-bit image as (h, w, c) codes in RGB order (c = 1 for grey), alpha dropped."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise UserInputError("cannot read the image (unreadable or truncated)", file=path)
    if image.dtype not in (np.uint8, np.uint16):
        raise UserInputError("unsupported sample type", file=path, expected="8- or 16-bit integer samples",
                             got=str(image.dtype))
    if image.ndim == 2:
        return image[:, :, None]
    if image.shape[2] == 4:
        image = image[:, :, :3]
    return np.ascontiguousarray(image[:, :, ::-1]) if image.shape[2] == 3 else image[:, :, :1]


def _levels(codes: np.ndarray, bits: int) -> np.ndarray:
    """Local (5 x 5) means of the normalised values, per channel."""
    values = codes.astype(np.float32) / float(2**bits - 1)
    return cv2.blur(values, (5, 5), borderType=cv2.BORDER_REFLECT).reshape(values.shape)


def _usable(codes: np.ndarray, levels: np.ndarray, bits: int) -> np.ndarray:
    """Values that are not clipped (the lowest or highest code), whose neighbourhood is
    neither dark nor saturated, and that are not next to a saturated pixel."""
    top = 2**bits - 1
    saturated = ((levels >= SATURATED) | (codes >= top)).any(axis=2).astype(np.uint8)
    size = 2 * SATURATION_RADIUS_PX + 1
    near = cv2.dilate(saturated, np.ones((size, size), np.uint8)).astype(bool)
    return (codes > 0) & (levels > DARK_CODES / 255.0) & ~near[:, :, None]


def _check_exposed(path: Path, usable: np.ndarray, saturated_share: float) -> None:
    if usable.mean() < USABLE_FRACTION_MIN:
        what = "saturated" if saturated_share > 0.5 else "black"
        raise UserInputError(f"the image is {what} everywhere: it holds no usable values", file=path,
                             expected=f"at least {USABLE_FRACTION_MIN:.1%} of values between black and saturation",
                             got=f"{usable.mean():.4%}")


def read_bracket(paths: Sequence[str | Path], times_s: Sequence[float] | None = None) -> Bracket:
    """Read a bracket of 8/16-bit JPEG, PNG or TIFF images (same size, channels and depth)
    and its exposure times; images larger than MAX_PIXELS are kept at a stride."""
    checked = check_paths(paths)
    if is_raw(checked[0]):
        raise UserInputError("raw files have no response curve to fit", field="IMAGE",
                             expected="JPEG/PNG/TIFF images (raw brackets are checked with raw_linearity)")
    times = exposure_times(checked, times_s)
    _check_times(checked, times)
    first = _read_codes(checked[0])
    bits = 8 if first.dtype == np.uint8 else 16
    stride = max(1, math.ceil(math.sqrt(first.shape[0] * first.shape[1] / MAX_PIXELS)))
    frames = [_bracket_frame(checked[0], first, bits, stride)]
    for path in checked[1:]:
        image = _read_codes(path)
        if image.shape != first.shape or image.dtype != first.dtype:
            raise UserInputError("the image differs from the bracket's first image", file=path,
                                 expected=f"{_describe(first)} like {checked[0].name}", got=_describe(image))
        frames.append(_bracket_frame(path, image, bits, stride))
    codes, levels, usable = (np.stack(parts) for parts in zip(*frames, strict=True))
    channels = ("R", "G", "B") if first.shape[2] == 3 else ("grey",)
    return Bracket(codes, levels, usable, times, bits, tuple(str(p) for p in checked), channels, stride)


def _bracket_frame(path: Path, image: np.ndarray, bits: int, stride: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One image's codes, local levels and usable mask (kept at ``stride``); an image with
    almost nothing usable is refused by name."""
    level = _levels(image, bits)
    usable = _usable(image, level, bits)
    _check_exposed(path, usable, float((level >= SATURATED).mean()))
    return image[::stride, ::stride], level[::stride, ::stride], usable[::stride, ::stride]


def _describe(image: np.ndarray) -> str:
    h, w, c = image.shape
    return f"{w} x {h}, {c} channel{'s' if c > 1 else ''}, {image.dtype.itemsize * 8}-bit"


def _read_raw(path: Path) -> np.ndarray:
    """Raw values normalised by the black level (per CFA channel) and the white level."""
    import rawpy  # deferred: start-up time

    try:
        with rawpy.imread(str(path)) as raw:
            counts = raw.raw_image_visible.astype(np.float64)
            black = np.asarray(raw.black_level_per_channel, dtype=float)[raw.raw_colors_visible]
            white = float(raw.white_level)
    except (rawpy.LibRawError, OSError) as error:
        raise UserInputError(f"cannot read the raw file ({error})", file=path) from None
    return (counts - black) / (white - black)


def _same_colour_mean(mosaic: np.ndarray) -> np.ndarray:
    """Mean over a pixel's 3 x 3 neighbours of its own colour in a 2 x 2 CFA (offsets of 0 and
    +-2 pixels): the local level that decides whether a raw value is usable, without its
    own noise deciding it (Bayer and X-Trans-like 2 x 2 patterns)."""
    kernel = np.zeros((5, 5), np.float32)
    kernel[::2, ::2] = 1.0 / 9.0
    return cv2.filter2D(mosaic.astype(np.float32), -1, kernel, borderType=cv2.BORDER_REFLECT)


def _raw_frame(path: Path, shape: tuple[int, ...] | None) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """One raw frame's normalised values and usable mask (local level within RAW_USABLE),
    at a stride for large sensors, and its full size."""
    v = _read_raw(path)
    if shape is not None and v.shape != shape:
        raise UserInputError("the raw image differs in size from the bracket's first", file=path,
                             expected=f"{shape[1]} x {shape[0]}", got=f"{v.shape[1]} x {v.shape[0]}")
    level = _same_colour_mean(v)
    usable = (level > RAW_USABLE[0]) & (level < RAW_USABLE[1]) & (v < 1.0)
    _check_exposed(path, usable, float((level >= SATURATED).mean()))
    stride = 1 if v.size <= MAX_PIXELS else 2 * math.ceil(math.sqrt(v.size / MAX_PIXELS) / 2)  # even: keeps the CFA
    return v[::stride, ::stride], usable[::stride, ::stride], v.shape


def read_raw_bracket(paths: Sequence[str | Path], times_s: Sequence[float] | None = None) -> RawBracket:
    """Read a raw bracket (same sensor size) and its exposure times."""
    checked = check_paths(paths)
    times = exposure_times(checked, times_s)
    _check_times(checked, times)
    first = _raw_frame(checked[0], None)
    frames = [first] + [_raw_frame(path, first[2]) for path in checked[1:]]
    values = np.stack([frame.ravel() for frame, _, _ in frames], 1)
    usable = np.stack([mask.ravel() for _, mask, _ in frames], 1).astype(float)
    return RawBracket(values, usable, times)

"""Reading an exposure bracket for calibration.response.calibrate: the images' codes, their local
levels and which values are usable, and the exposure times (``--times`` or each file's
EXIF: calibration.raw.decode.read_exif, LibRaw's shutter time for raw formats without TIFF
tags); for a raw bracket, the raw values normalised by the black and white levels.

Units: images enter as integer codes (8 or 16 bits) and are normalised to values
y = code / (2^bits - 1) in [0, 1]; raw values as (count - black) / (white - black); times
in seconds.

Before any fit, the frames are checked against their times (``check_frames_follow_times``,
``check_raw_follows_times``): each pair of frames consecutive in time, over the values both
see well exposed, must show its claimed exposure ratio (raw: the measured ratio itself;
developed images: the ordering a monotone response implies), else the bracket is refused
naming the pair.
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

# Frames against their claimed times (check_frames_follow_times, check_raw_follows_times).
# A pair is judged on the values both frames see well exposed (usable in both), and only
# where there are PAIR_VALUES_MIN of them (fewer: the fit's own overlap check speaks).
PAIR_VALUES_MIN = 100
# Developed images: a monotone response ([Debevec 1997, Sec. 2.1, Eq. 1]) makes the longer
# exposure brighter wherever neither frame is clipped. Measured share of well-exposed values
# brighter in the longer frame: 0.924-0.995 on the draft dataset's JPEG bracket (ev-6..ev+2,
# x2 and x4 steps; lowest in the brightest pair, JPEG artefacts beside highlights), 0.995-1.000
# on tests/calibration/test_response.py's PNG brackets (sRGB and shoulder curves, 5 seeds);
# the same bracket in reverse order 0.004-0.055, the same frame twice 0 (all equal). "Most"
# is more than ORDER_SHARE_MIN: 0.42 above the reversed maximum and below the correct minimum.
ORDER_SHARE_MIN = 0.5
# Two frames whose well-exposed codes are equal at more than this share are the same image
# (correct pairs: at most 0.020 equal; a frame twice: 1.000).
IDENTICAL_SHARE = 0.9
# Raw frames: the median ratio of the pixels' values (linear: no response needed) is the
# exposure ratio. Measured against the true ratio: within 0.06 % on the draft dataset's DNG
# bracket (6 pairs) and 0.10 % on test_response.py's synthetic DNG brackets (5 seeds x 4
# pairs), shot noise being the only error. A camera's marked times are nominal: 1/60 and
# 1/125 s are marked x2.083 apart for a true x2 (powers of two), 4.2 %, and a mechanical
# shutter's short times scatter by a few per cent more; RAW_RATIO_TOLERANCE (10 %) leaves room
# for both and refuses a time that is wrong by more, a frame twice (x1) or reversed times (x1/c).
RAW_RATIO_TOLERANCE = 0.10
# A raw sensor may be non-linear (value ~ (E t)^b, b reported by the linearity check), so
# the ratios are compared with the claimed ones raised to the bracket's common exponent b
# (the median over pairs of ln measured / ln claimed). A pair whose own exponent lies outside
# RAW_EXPONENT_RANGE is no sensor's response but wrong times: identical frames give 0,
# reversed ones -1 (the synthetic non-linear raw of test_response.py: 0.80).
RAW_EXPONENT_RANGE = (0.5, 2.0)


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
    files: tuple[str, ...] = ()


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
    bracket = Bracket(codes, levels, usable, times, bits, tuple(str(p) for p in checked), channels, stride)
    check_frames_follow_times(bracket)
    return bracket


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
    bracket = RawBracket(values, usable, times, tuple(str(p) for p in checked))
    check_raw_follows_times(bracket)
    return bracket



def _pairs_in_time(times: np.ndarray) -> list[tuple[int, int]]:
    """Indices (shorter, longer) of the frames consecutive in exposure time; frames of equal
    times are not a pair (nothing is claimed between them)."""
    order = np.argsort(times, kind="stable")
    return [(int(i), int(j)) for i, j in zip(order[:-1], order[1:], strict=True) if times[j] > times[i]]


def _contradiction(files: Sequence[str], times: np.ndarray, pair: tuple[int, int], measured: str) -> UserInputError:
    """The one-line refusal naming the pair of files, the claimed ratio and the measured one."""
    i, j = pair
    return UserInputError(f"{files[i]} ({times[i]:g} s) and {files[j]} ({times[j]:g} s) contradict their exposure "
                          f"times: claimed x{times[j] / times[i]:.3f}, measured {measured}", field="exposure times",
                          expected="frames whose brightness follows their times (EXIF ExposureTime, or --times in "
                                   "the order the files are given)")


def check_frames_follow_times(bracket: Bracket) -> None:
    """Refuse developed frames that contradict their times. The response f is unknown but
    monotone, Z = f(E t) ([Debevec 1997, Sec. 2.1, Eq. 1]), so of two frames the longer
    exposure is brighter at every value neither clips: over the values both frames see well
    exposed (``usable`` in both), the longer one must be brighter at more than
    ORDER_SHARE_MIN of them, and frames whose codes are equal at more than IDENTICAL_SHARE
    are the same image. Only the ordering is tested: the ratio itself needs the curve."""
    for i, j in _pairs_in_time(bracket.times_s):
        both = bracket.usable[i] & bracket.usable[j]
        count = int(both.sum())
        if count < PAIR_VALUES_MIN:
            continue
        short, long = bracket.codes[i][both], bracket.codes[j][both]
        equal, brighter, darker = (float(np.mean(test)) for test in (long == short, long > short, long < short))
        if equal > IDENTICAL_SHARE:
            raise _contradiction(bracket.files, bracket.times_s, (i, j),
                                 f"x1, the same image ({equal:.1%} of {count} well-exposed values equal)")
        if brighter <= ORDER_SHARE_MIN:
            raise _contradiction(bracket.files, bracket.times_s, (i, j),
                                 f"not above x1 (the longer exposure brighter at {brighter:.1%} and darker at "
                                 f"{darker:.1%} of {count} well-exposed values; a response is monotone: brighter at "
                                 "most)")


def raw_pair_ratios(bracket: RawBracket) -> list[tuple[tuple[int, int], float, float, int]]:
    """Each pair of raw frames consecutive in time: ((shorter, longer), claimed ratio, measured
    ratio, values used). The measured ratio is the median over the pixels both frames see well
    exposed (within RAW_USABLE in both) of longer / shorter: raw values are linear in the
    exposure ([EMVA 1288, Sec. 2]), and the median ([Hampel 1986]) ignores the few pixels a
    moving object or a hot pixel changes. Pairs with fewer than PAIR_VALUES_MIN such pixels
    are left out."""
    rows = []
    for i, j in _pairs_in_time(bracket.times_s):
        v = bracket.values
        both = (bracket.usable[:, i] > 0) & (bracket.usable[:, j] > 0) & (v[:, i] > 0) & (v[:, j] > 0)
        if int(both.sum()) >= PAIR_VALUES_MIN:
            measured = float(np.median(v[both, j] / v[both, i]))
            rows.append(((i, j), float(bracket.times_s[j] / bracket.times_s[i]), measured, int(both.sum())))
    return rows


def check_raw_follows_times(bracket: RawBracket) -> None:
    """Refuse a raw bracket whose measured exposure ratios (raw_pair_ratios) contradict the
    claimed ones: a pair whose exponent ln(measured) / ln(claimed) lies outside
    RAW_EXPONENT_RANGE (the same frame twice: 0; reversed times: -1), or, with two pairs or
    more, a pair off the bracket's common power law (value ~ (E t)^b, b the median exponent,
    1 for a linear sensor; [EMVA 1288, Sec. 6.4]) by more than RAW_RATIO_TOLERANCE. A common
    b other than 1 is left to the linearity check to report."""
    files = bracket.files or tuple(f"frame {k + 1}" for k in range(len(bracket.times_s)))
    rows = raw_pair_ratios(bracket)
    exponents = [math.log(measured) / math.log(claimed) for _, claimed, measured, _ in rows]
    for (pair, _, measured, count), exponent in zip(rows, exponents, strict=True):
        if not RAW_EXPONENT_RANGE[0] <= exponent <= RAW_EXPONENT_RANGE[1]:
            same = " (the same exposure)" if abs(math.log(measured)) < math.log1p(RAW_RATIO_TOLERANCE) else ""
            raise _contradiction(files, bracket.times_s, pair,
                                 f"x{measured:.3f}{same}, the median ratio of {count} well-exposed raw values")
    if len(rows) < 2:
        return
    b = float(np.median(exponents))
    misfit = [abs(math.log(measured) - b * math.log(claimed)) for _, claimed, measured, _ in rows]
    worst = int(np.argmax(misfit))
    if misfit[worst] > math.log1p(RAW_RATIO_TOLERANCE):
        pair, claimed, measured, count = rows[worst]
        raise _contradiction(files, bracket.times_s, pair,
                             f"x{measured:.3f}, the median ratio of {count} well-exposed raw values (the bracket's "
                             f"other pairs follow their times to the power {b:.3f}: x{claimed ** b:.3f} here, "
                             f"tolerance {RAW_RATIO_TOLERANCE:.0%})")

"""Writing raw Bayer images as DNG files that rawpy (LibRaw) reads back.

A DNG is a TIFF with a CFA image and the tags of the DNG specification [DNG 1.4]:
we write, in IFD 0, NewSubFileType 0, PhotometricInterpretation 32803 (CFA),
CFARepeatPatternDim / CFAPattern ([TIFF/EP]), DNGVersion 1.4 and DNGBackwardVersion 1.1,
UniqueCameraModel, Make, Model, BlackLevel, WhiteLevel, ColorMatrix1 with
CalibrationIlluminant1, AsShotNeutral, ExposureTime and ISOSpeedRatings; uncompressed
16-bit samples. tifffile writes the TIFF (its extratags); the file is written to a
temporary name and renamed, so a crash never leaves half a file. LibRaw refuses tiny
images, so both sides must be at least MIN_SIDE pixels.

Besides a 2 x 2 Bayer mosaic, for decoding tests of other sensor layouts: a square RGB
pattern of any period (``cfa_pattern`` of n * n letters, row-major: a Fujifilm X-Trans
6 x 6 has 36), written with CFARepeatPatternDim (n, n); and, with ``cfa_pattern=""``, a
raw without a filter array, PhotometricInterpretation LinearRaw (34892) [DNG 1.4, Ch. 4]:
(H, W, 3) samples (a linear DNG) or (H, W) (a monochrome sensor). tifffile writes no
one-sample LinearRaw, so that one is written as BlackIsZero and its
PhotometricInterpretation value set to 34892 in place before the rename.

A four-colour 2 x 2 array (four distinct letters of R, G, B, C, M, Y, W, e.g. "CMYG"; the
CFAPattern codes of [TIFF/EP, CFAPattern]: 0 red, 1 green, 2 blue, 3 cyan, 4 magenta,
5 yellow, 6 white) is written with CFAPlaneColor, the planes in the order their colours
first appear in the pattern, and a ColorMatrix1 and AsShotNeutral of one row or entry per
plane ([DNG 1.4, Ch. 6]). Given a 3 x 3 ``color_matrix`` (XYZ to the RGB the filters are
made of), each plane's row is the sum of the rows of the colours its ideal filter passes
(cyan = green + blue, magenta = red + blue, yellow = red + green, white = all three).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
import tifffile

from workbench.core.files import atomic_write

CFA_CODES = {"R": 0, "G": 1, "B": 2, "C": 3, "M": 4, "Y": 5, "W": 6}   # TIFF/EP CFAPattern codes
PASSES = {"R": (1, 0, 0), "G": (0, 1, 0), "B": (0, 0, 1), "C": (0, 1, 1), "M": (1, 0, 1), "Y": (1, 1, 0),
          "W": (1, 1, 1)}   # the red, green and blue an ideal filter of each colour passes
MIN_SIDE = 32
D65 = 21  # EXIF LightSource code for CalibrationIlluminant1
LINEAR_RAW = 34892  # PhotometricInterpretation LinearRaw [DNG 1.4]
BLACK_IS_ZERO = 1


@dataclass(frozen=True)
class DngMetadata:
    cfa_pattern: str = "RGGB"                 # row-major 2x2
    black_level: int = 512
    white_level: int = 16383                   # 14-bit
    color_matrix: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)  # XYZ (D65) -> camera, row-major
    as_shot_neutral: tuple[float, float, float] = (1.0, 1.0, 1.0)
    exposure_time_s: float = 0.01
    iso: int = 100
    make: str = "Workbench"
    model: str = "Synthetic RGGB"


def _rational(x: float, signed: bool, den_limit: int = 1_000_000) -> tuple[int, int]:
    f = Fraction(x).limit_denominator(den_limit)
    if not signed and f < 0:
        raise ValueError("unsigned rational must be >= 0")
    return f.numerator, f.denominator


def _flat(values, signed: bool) -> tuple[int, ...]:
    out: list[int] = []
    for v in values:
        out += list(_rational(float(v), signed))
    return tuple(out)


def write_dng(path: str | Path, raw: np.ndarray, meta: DngMetadata) -> Path:
    """Write a 2D uint16 mosaic (or, with ``meta.cfa_pattern == ""``, a linear (H, W, 3) or monochrome (H, W) raw)
    as a DNG; returns the path."""
    raw = np.asarray(raw)
    linear = meta.cfa_pattern == ""
    if raw.dtype != np.uint16 or not (raw.ndim == 2 or (linear and raw.ndim == 3 and raw.shape[2] == 3)):
        raise ValueError(f"raw must be a 2D uint16 mosaic (or (H, W, 3) without a CFA), got {raw.dtype} {raw.shape}")
    if min(raw.shape[:2]) < MIN_SIDE:
        raise ValueError(f"raw images must be at least {MIN_SIDE} x {MIN_SIDE} pixels (LibRaw refuses smaller), got {raw.shape}")
    side = _pattern_side(meta.cfa_pattern)
    samples = 1 if raw.ndim == 2 else 3
    planes = _planes(meta.cfa_pattern)
    matrix, neutral = _plane_colour(meta, planes)
    tags = [
        (50706, 1, 4, (1, 4, 0, 0), True),                                   # DNGVersion
        (50707, 1, 4, (1, 1, 0, 0), True),                                   # DNGBackwardVersion
        (50708, 2, 0, f"{meta.make} {meta.model}", True),                   # UniqueCameraModel
        (271, 2, 0, meta.make, True),                                       # Make
        (272, 2, 0, meta.model, True),                                      # Model
        *([] if linear else [
            (33421, 3, 2, (side, side), True),                              # CFARepeatPatternDim
            (33422, 1, side * side, tuple(CFA_CODES[c] for c in meta.cfa_pattern), True)]),  # CFAPattern
        *([(50710, 1, len(planes), tuple(CFA_CODES[c] for c in planes), True)]                # CFAPlaneColor
          if len(planes) == 4 else []),
        (50714, 3, samples, (int(meta.black_level),) * samples, True),      # BlackLevel
        (50717, 3, samples, (int(meta.white_level),) * samples, True),      # WhiteLevel
        (50721, 10, len(matrix), _flat(matrix, signed=True), True),         # ColorMatrix1 (SRATIONAL)
        (50778, 3, 1, (D65,), True),                                        # CalibrationIlluminant1
        (50728, 5, len(neutral), _flat(neutral, signed=False), True),       # AsShotNeutral (RATIONAL)
        (33434, 5, 1, _rational(meta.exposure_time_s, signed=False), True),  # ExposureTime
        (34855, 3, 1, (int(meta.iso),), True),                              # ISOSpeedRatings
    ]
    photometric = LINEAR_RAW if samples == 3 else (BLACK_IS_ZERO if linear else 32803)

    def write(tmp: Path) -> None:
        tifffile.imwrite(tmp, raw, photometric=photometric, extratags=tags, subfiletype=0, metadata=None,
                         compression=None)
        if linear and samples == 1:
            _set_photometric(tmp, LINEAR_RAW)

    return atomic_write(path, write)


def _pattern_side(pattern: str) -> int:
    """The period of a square row-major CFA pattern (2 for Bayer, 6 for X-Trans); 0 for no CFA."""
    if pattern == "":
        return 0
    side = int(round(len(pattern) ** 0.5))
    if len(pattern) == 4 and (sorted(pattern) == sorted("RGGB") or (len(set(pattern)) == 4
                                                                    and set(pattern) <= set(CFA_CODES))):
        return 2
    if len(pattern) > 4 and side * side == len(pattern) and set(pattern) == set("RGB"):
        return side
    raise ValueError(f"cfa_pattern must be a 2x2 Bayer pattern such as 'RGGB', a 2x2 pattern of four colours of "
                     f"{''.join(CFA_CODES)} such as 'CMYG', an n x n RGB pattern (36 letters for X-Trans) or '' (no CFA), "
                     f"got {pattern!r}")


def _planes(pattern: str) -> str:
    """The colour planes of a CFA pattern, in the order they first appear; RGB for a three-colour one."""
    distinct = "".join(dict.fromkeys(pattern))
    return distinct if len(distinct) == 4 else "RGB"


def _plane_colour(meta: DngMetadata, planes: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """ColorMatrix1 (one row of 3 per plane) and AsShotNeutral (one per plane) for ``planes`` (see the module
    docstring): ``meta``'s own for RGB, or for four planes the sums of the rows of the colours each filter passes."""
    if planes == "RGB" or len(meta.color_matrix) == 3 * len(planes):
        return tuple(meta.color_matrix), tuple(meta.as_shot_neutral)
    passes = np.array([PASSES[c] for c in planes], float)
    matrix = passes @ np.asarray(meta.color_matrix, float).reshape(3, 3)
    neutral = passes @ np.asarray(meta.as_shot_neutral, float)
    return tuple(matrix.ravel()), tuple(neutral / neutral.max())


def _set_photometric(path: Path, value: int) -> None:
    """Overwrite IFD 0's PhotometricInterpretation (a SHORT held in its IFD entry) with ``value``."""
    with tifffile.TiffFile(path) as tif:
        tag = tif.pages.first.tags["PhotometricInterpretation"]
        offset, order = tag.valueoffset, tif.byteorder
    with open(path, "r+b") as handle:
        handle.seek(offset)
        handle.write(struct.pack(order + "H", value))

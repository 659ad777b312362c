"""Writing raw Bayer images as DNG files that rawpy (LibRaw) reads back.

A DNG is a TIFF with a CFA image and the tags of the DNG specification [DNG 1.4]:
we write, in IFD 0, NewSubFileType 0, PhotometricInterpretation 32803 (CFA),
CFARepeatPatternDim / CFAPattern ([TIFF/EP]), DNGVersion 1.4 and DNGBackwardVersion 1.1,
UniqueCameraModel, Make, Model, BlackLevel, WhiteLevel, ColorMatrix1 with
CalibrationIlluminant1, AsShotNeutral, ExposureTime and ISOSpeedRatings; uncompressed
16-bit samples. tifffile writes the TIFF (its extratags); the file is written to a
temporary name and renamed, so a crash never leaves half a file. LibRaw refuses tiny
images, so both sides must be at least MIN_SIDE pixels.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
import tifffile

from workbench.core.files import atomic_write

CFA_CODES = {"R": 0, "G": 1, "B": 2}
MIN_SIDE = 32
D65 = 21  # EXIF LightSource code for CalibrationIlluminant1


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
    """Write a 2D uint16 Bayer mosaic as a DNG; returns the path."""
    raw = np.asarray(raw)
    if raw.ndim != 2 or raw.dtype != np.uint16:
        raise ValueError(f"raw must be a 2D uint16 mosaic, got {raw.dtype} {raw.shape}")
    if min(raw.shape) < MIN_SIDE:
        raise ValueError(f"raw images must be at least {MIN_SIDE} x {MIN_SIDE} pixels (LibRaw refuses smaller), got {raw.shape}")
    if sorted(meta.cfa_pattern) != sorted("RGGB") or len(meta.cfa_pattern) != 4:
        raise ValueError(f"cfa_pattern must be a 2x2 Bayer pattern such as 'RGGB', got {meta.cfa_pattern!r}")
    tags = [
        (50706, 1, 4, (1, 4, 0, 0), True),                                   # DNGVersion
        (50707, 1, 4, (1, 1, 0, 0), True),                                   # DNGBackwardVersion
        (50708, 2, 0, f"{meta.make} {meta.model}", True),                   # UniqueCameraModel
        (271, 2, 0, meta.make, True),                                       # Make
        (272, 2, 0, meta.model, True),                                      # Model
        (33421, 3, 2, (2, 2), True),                                        # CFARepeatPatternDim
        (33422, 1, 4, tuple(CFA_CODES[c] for c in meta.cfa_pattern), True),  # CFAPattern
        (50714, 3, 1, (int(meta.black_level),), True),                      # BlackLevel
        (50717, 3, 1, (int(meta.white_level),), True),                      # WhiteLevel
        (50721, 10, 9, _flat(meta.color_matrix, signed=True), True),        # ColorMatrix1 (SRATIONAL)
        (50778, 3, 1, (D65,), True),                                        # CalibrationIlluminant1
        (50728, 5, 3, _flat(meta.as_shot_neutral, signed=False), True),     # AsShotNeutral (RATIONAL)
        (33434, 5, 1, _rational(meta.exposure_time_s, signed=False), True),  # ExposureTime
        (34855, 3, 1, (int(meta.iso),), True),                              # ISOSpeedRatings
    ]
    def write(tmp: Path) -> None:
        tifffile.imwrite(tmp, raw, photometric=32803, extratags=tags, subfiletype=0, metadata=None, compression=None)

    return atomic_write(path, write)

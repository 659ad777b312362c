"""A scene photograph as linear camera RGB, for pose fitting and photometry.

calibration.raw.decode does the reading: raw files (anything LibRaw reads) to linear camera
RGB with 1 at the white level (black level subtracted per channel, no white balance, no
gamma, bilinear demosaicing), the saturation mask and the EXIF exposure time; JPEG, PNG
and TIFF through an inverse response when one is given (flagged non-linear when none is).
Here that becomes a ``Photo`` with three channels (a grey image is repeated), and
``mosaic_like`` takes a render through the same colour filter array and demosaicing, so
that an edge in the render blurs exactly as it does in the photo (calibration.pose.calibrate's
render check).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calibration.raw.decode import RAW_EXTENSIONS, bilinear_demosaic, cfa_channels, decode, is_raw

RAW_SUFFIXES = RAW_EXTENSIONS


@dataclass(frozen=True)
class Photo:
    path: str
    rgb: np.ndarray          # float32 (H, W, 3), linear camera RGB; 1 = the white level
    saturated: np.ndarray    # bool (H, W)
    linear: bool             # False for a non-raw image read without an inverse response
    exposure_time_s: float | None
    cfa: str | None          # e.g. "RGGB" for raws

    @property
    def width(self) -> int:
        return int(self.rgb.shape[1])

    @property
    def height(self) -> int:
        return int(self.rgb.shape[0])

    @property
    def grey(self) -> np.ndarray:
        return self.rgb.mean(axis=2)


def read_photo(path: str | Path, inverse_response: Callable[[np.ndarray], np.ndarray] | None = None) -> Photo:
    """The photo at ``path`` as linear RGB (calibration.raw.decode); ``inverse_response``, from
    normalised value to normalised irradiance, applies to non-raw images only."""
    decoded = decode(path, response=None if is_raw(path) else inverse_response, response_for_codes_only=True)
    rgb = decoded.rgb(path)
    info = decoded.info
    return Photo(str(path), rgb, decoded.saturated, bool(info.linear), info.exposure_time_s, info.cfa)


def mosaic_like(rgb: np.ndarray, cfa: str | None) -> np.ndarray:
    """``rgb`` (H, W, 3) through a 2 x 2 colour filter array ``cfa`` (e.g. "RGGB", row-major)
    and calibration.raw.decode's bilinear demosaicing; unchanged when there is no CFA."""
    channel = cfa_channels(cfa, rgb.shape[:2])
    if channel is None:
        return rgb
    mosaic = np.take_along_axis(rgb, channel[..., None], axis=2)[..., 0]
    return bilinear_demosaic(np.ascontiguousarray(mosaic, np.float32), channel)

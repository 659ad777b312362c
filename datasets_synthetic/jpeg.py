"""The camera's own JPEG: a raw frame developed through a hidden, non-linear response.

What a camera in RAW+JPEG mode does, reduced to the steps that matter for recovering its
response from exposure brackets ([Debevec 1997, Sec. 2]: pixel value Z = f(E t), one
monotone f per channel):
1. demosaic the raw mosaic (OpenCV's bilinear Bayer interpolation);
2. normalise to irradiance x = (raw - black) / (white - black), clipped to [0, 1]
   (a clipped raw value gives x = 1);
3. apply the response y = f(x) (no white balance or colour matrix: camera RGB, so the
   response is the only non-linearity);
4. quantise to 8 bits and compress (JPEG, quality 95, no chroma subsampling), with the
   exposure time, ISO, make and model in its EXIF, as a camera writes them.

The hidden response is a power law with an S-shaped contrast term,
f(x) = y + c sin(2 pi y) / (2 pi) with y = x^(1/gamma) and -0.3 < c < 0: f(0) = 0,
f(1) = 1 and f' >= 1 - |c| > 0, so it is monotone. It is stored, and applied, as samples
interpolated with a monotone cubic (renderer.response, kind "points"): the curve in
truth.json is exactly the one the JPEGs went through.
"""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import cv2
import numpy as np
from PIL import Image, TiffImagePlugin

from renderer.response import ResponseCurve
from workbench.core.files import atomic_write

# OpenCV names a Bayer pattern by the 2x2 block starting at the second row and column.
OPENCV_BAYER = {"RGGB": cv2.COLOR_BayerBG2RGB, "BGGR": cv2.COLOR_BayerRG2RGB,
                "GRBG": cv2.COLOR_BayerGB2RGB, "GBRG": cv2.COLOR_BayerGR2RGB}
JPEG_QUALITY = 95
RESPONSE_SAMPLES = 65


def hidden_response(rng: np.random.Generator) -> ResponseCurve:
    """A seeded camera-like response: gamma 1.9-2.5 with an S-shaped contrast term."""
    gamma = rng.uniform(1.9, 2.5)
    c = -rng.uniform(0.1, 0.3)
    x = np.linspace(0.0, 1.0, RESPONSE_SAMPLES) ** 2  # denser where the power law is steep
    y = x ** (1.0 / gamma)
    f = y + c * np.sin(2 * math.pi * y) / (2 * math.pi)
    f[0], f[-1] = 0.0, 1.0
    return ResponseCurve("points", 1.0, tuple((float(a), float(b)) for a, b in zip(x, f, strict=True)))


def demosaic(raw: np.ndarray, cfa_pattern: str) -> np.ndarray:
    """Bilinear demosaic of a uint16 Bayer mosaic to (H, W, 3) uint16 camera RGB."""
    return cv2.cvtColor(np.ascontiguousarray(raw, dtype=np.uint16), OPENCV_BAYER[cfa_pattern])


def develop(raw: np.ndarray, sensor, response: ResponseCurve) -> np.ndarray:
    """Raw mosaic to 8-bit camera RGB through the response (steps 1-3 above, then rounding)."""
    rgb = demosaic(raw, sensor.cfa_pattern).astype(float)
    x = np.clip((rgb - sensor.black_level) / (sensor.white_level - sensor.black_level), 0.0, 1.0)
    return np.rint(255.0 * response.apply(x)).astype(np.uint8)


def write_jpeg(path: str | Path, rgb8: np.ndarray, *, exposure_time_s: float, iso: int, make: str, model: str) -> Path:
    """An 8-bit RGB image as a JPEG with EXIF Make, Model, ExposureTime and ISO (Pillow)."""
    exif = Image.Exif()
    exif[0x010F], exif[0x0110] = make, model
    sub = exif.get_ifd(0x8769)  # the Exif sub-IFD
    t = Fraction(exposure_time_s).limit_denominator(1_000_000)
    sub[0x829A] = TiffImagePlugin.IFDRational(t.numerator, t.denominator)  # ExposureTime
    sub[0x8827] = int(iso)                                                   # ISOSpeedRatings
    image = Image.fromarray(np.ascontiguousarray(rgb8), "RGB")
    return atomic_write(path, lambda tmp: image.save(tmp, format="JPEG", quality=JPEG_QUALITY, subsampling=0, exif=exif))


def read_exposure_time(path: str | Path) -> float:
    """The ExposureTime a JPEG's EXIF holds, in seconds."""
    with Image.open(path) as image:
        return float(image.getexif().get_ifd(0x8769)[0x829A])

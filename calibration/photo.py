"""A scene photograph as linear camera RGB, for pose fitting and photometry.

Raw files (anything LibRaw reads: DNG, NEF, CR2, ...) through rawpy: the visible mosaic,
per-channel black level subtracted, divided by (white level - black), so 1 is the white
level; no white balance, no gamma, no brightening. Demosaicing is bilinear by normalised
convolution (each channel's samples and its mask blurred by the same 3 x 3 tent, then
divided: H. Knutsson and C.-F. Westin, "Normalized and differential convolution", CVPR
1993), which works for any 2 x 2 pattern and moves no edge: the tent is symmetric. A pixel
is saturated where its own raw value reaches the white level (dilated by the demosaic's
reach). Non-raw images (8/16-bit JPEG, PNG, TIFF) pass through an inverse response
(calibration.response's ``points``) when one is given, and are marked non-linear when
none is.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from workbench.core.errors import UserInputError

RAW_SUFFIXES = {".dng", ".nef", ".cr2", ".cr3", ".arw", ".orf", ".rw2", ".raf", ".pef", ".srw", ".raw", ".nrw", ".3fr", ".iiq"}
TENT = np.array([[1, 2, 1], [2, 4, 2], [1, 2, 1]], np.float32) / 4.0
SATURATION_MARGIN = 0.0  # a raw value >= white level - margin is saturated


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


def demosaic_bilinear(mosaic: np.ndarray, colors: np.ndarray) -> np.ndarray:
    """(H, W) float mosaic and (H, W) channel index (0 R, 1 G, 2 B) -> (H, W, 3), bilinear."""
    out = np.empty(mosaic.shape + (3,), np.float32)
    for c in range(3):
        mask = (colors == c).astype(np.float32)
        num = cv2.filter2D(mosaic.astype(np.float32) * mask, -1, TENT, borderType=cv2.BORDER_REFLECT)
        den = cv2.filter2D(mask, -1, TENT, borderType=cv2.BORDER_REFLECT)
        out[..., c] = num / np.maximum(den, 1e-6)
    return out


def read_photo(path: str | Path, inverse_response=None) -> Photo:
    """The photo at ``path`` as linear RGB (see the module docstring); ``inverse_response``:
    a callable from normalised value to normalised irradiance, for non-raw images."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError("no such photo", file=path, expected="a raw file (DNG, NEF, CR2, ...) or a JPEG, PNG or TIFF")
    if path.suffix.lower() in RAW_SUFFIXES:
        return _read_raw(path)
    return _read_image(path, inverse_response)


def _read_raw(path: Path) -> Photo:
    import rawpy

    try:
        with rawpy.imread(str(path)) as raw:
            mosaic = raw.raw_image_visible.astype(np.float32)
            index = raw.raw_colors_visible.copy()
            desc = raw.color_desc.decode()
            black = np.asarray(raw.black_level_per_channel, np.float32)
            white = float(raw.white_level)
            pattern = "".join(desc[i] for i in np.asarray(raw.raw_pattern).ravel())
    except (rawpy.LibRawError, OSError, ValueError) as exc:
        raise UserInputError(f"cannot be read as a raw photo ({type(exc).__name__}: {exc})", file=path,
                             expected="a raw file LibRaw reads (DNG, NEF, CR2, ...)") from None
    channel = np.array(["RGB".index(desc[i]) if desc[i] in "RGB" else 1 for i in range(len(desc))])
    saturated_raw = mosaic >= white - SATURATION_MARGIN
    level = black[index]
    normalised = (mosaic - level) / np.maximum(white - level, 1.0)
    rgb = demosaic_bilinear(normalised, channel[index])
    saturated = cv2.dilate(saturated_raw.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    return Photo(str(path), rgb, saturated, True, exposure_time_s(path), pattern)


def exposure_time_s(path: Path) -> float | None:
    """EXIF ExposureTime (tag 33434) in seconds: in IFD 0 or the EXIF IFD of a TIFF-based
    file (DNG, NEF, CR2, ...; tifffile), or a JPEG's EXIF (Pillow); None when absent."""
    value = None
    try:
        import tifffile

        with tifffile.TiffFile(path) as tiff:
            tags = tiff.pages[0].tags
            tag = tags.get(33434)
            exif = tags.get(34665)
            value = tag.value if tag is not None else (exif.value.get("ExposureTime") if exif is not None else None)
    except Exception:  # noqa: BLE001 - not a TIFF container: try Pillow
        try:
            from PIL import Image

            with Image.open(path) as image:
                value = image.getexif().get_ifd(0x8769).get(33434)
        except Exception:  # noqa: BLE001 - no readable EXIF: no exposure time
            value = None
    if isinstance(value, tuple) and len(value) == 2:
        value = value[0] / value[1] if value[1] else None
    try:
        seconds = float(value) if value is not None else None
    except (TypeError, ValueError):
        return None
    return seconds if seconds is not None and seconds > 0 else None


def _read_image(path: Path, inverse_response) -> Photo:
    data = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if data is None:
        raise UserInputError("cannot be read as an image", file=path, expected="a raw file, or an 8/16-bit JPEG, PNG or TIFF")
    if data.dtype not in (np.uint8, np.uint16):
        raise UserInputError("unsupported pixel type", file=path, expected="8- or 16-bit integers", got=str(data.dtype))
    full = float(np.iinfo(data.dtype).max)
    values = data.astype(np.float32) / full
    if values.ndim == 2:
        values = np.repeat(values[..., None], 3, axis=2)
    rgb = np.ascontiguousarray(values[..., 2::-1] if values.shape[2] >= 3 else np.repeat(values[..., :1], 3, axis=2))
    saturated = np.any(data[..., :3] >= full, axis=2) if data.ndim == 3 else data >= full
    if inverse_response is not None:
        rgb = np.asarray(inverse_response(rgb), np.float32)
    return Photo(str(path), rgb, saturated, inverse_response is not None, exposure_time_s(path), None)

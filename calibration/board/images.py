"""Pixel arrays of any kind brought to the forms the corner finders need.

Photographs arrive as 8- or 16-bit integers (JPEG, PNG, TIFF), as floats (decoded raws,
EXR renders, arrays from other code), grey (H, W) or with channels (H, W, C). Two forms
come out:

* ``grey_unit``: float32 grey, the channels' mean, with the integer types' full scale at 1
  (8-bit / 255, 16-bit / 65535) and floats as they are: what the sub-pixel refinement
  reads (its criterion does not depend on the scale);
* ``grey_uint8``: the same stretched between its 0.5th and 99.5th percentiles to 0-255,
  what OpenCV's detectors read (they need 8 bits, and a dark linear raw or a 12-bit TIFF
  would otherwise use a few of its levels).
"""

from __future__ import annotations

import cv2
import numpy as np

from workbench.core.errors import UserInputError

STRETCH_PERCENTILES = (0.5, 99.5)
PERCENTILE_SAMPLES = 20_000


def grey_unit(image: np.ndarray, *, where: str = "image") -> np.ndarray:
    """``image`` (H, W) or (H, W, C), any integer or float type, as float32 grey (H, W)."""
    array = np.asarray(image)
    if array.ndim == 3 and array.shape[2] in (1, 2, 3, 4):
        colour = array[..., :3] if array.shape[2] >= 3 else array[..., :1]  # alpha and grey+alpha's alpha dropped
        array = colour.astype(np.float32).mean(axis=2) if colour.shape[2] > 1 else colour[..., 0]
    if array.ndim != 2 or min(array.shape) < 2:
        raise UserInputError("not an image", field=where, expected="an array (H, W) or (H, W, 1-4 channels)",
                             got=f"{array.dtype} {array.shape}")
    if np.issubdtype(array.dtype, np.integer):
        if array.dtype.itemsize > 2:
            raise UserInputError("unsupported integer type", field=where, expected="8- or 16-bit integers or floats",
                                 got=str(array.dtype))
        return (array.astype(np.float32) / float(np.iinfo(array.dtype).max)).astype(np.float32)
    if np.issubdtype(array.dtype, np.floating) or array.dtype == bool:
        grey = array.astype(np.float32)
        if not np.all(np.isfinite(grey)):
            raise UserInputError("the image holds NaN or infinite values", field=where)
        return grey
    raise UserInputError("unsupported pixel type", field=where, expected="8- or 16-bit integers or floats",
                         got=str(array.dtype))


def grey_uint8(grey: np.ndarray) -> np.ndarray:
    """Float grey stretched between its 0.5th and 99.5th percentiles to 0-255 (uint8)."""
    step = max(1, int(np.sqrt(grey.size / PERCENTILE_SAMPLES)))
    lo, hi = np.percentile(grey[::step, ::step], STRETCH_PERCENTILES)  # a regular subsample estimates them well
    if hi <= lo:
        return np.zeros(grey.shape, np.uint8)
    scale = 255.0 / (hi - lo)
    floored = np.maximum(np.asarray(grey, np.float32), np.float32(lo))  # convertScaleAbs takes |x|: nothing below lo
    return cv2.convertScaleAbs(floored, alpha=scale, beta=-lo * scale)  # rounds and saturates at 255

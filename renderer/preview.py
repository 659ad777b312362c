"""A render's PNG preview: white-balanced to the scene's light, at a white level you can fix.

The EXR is linear camera RGB; its preview is what a camera's as-shot development would show:
each channel divided by the camera RGB of a white diffuse surface under the scene's light
(the DNG AsShotNeutral, normalised so G = 1), so the box's white walls look grey, not
green; then the balanced value ``white_level`` is shown as white, and the rest with the
sRGB transfer curve (IEC 61966-2-1). By default the white level is the image's own 99.5th
percentile (each render exposed on its own); given (``--preview-white``) or taken from
another render's sidecar (``--preview-like``), a series of renders shares it and compares
by eye.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from renderer.spectra import light_camera_rgb
from workbench.core.errors import UserInputError

AUTO_PERCENTILE = 99.5  # of the balanced image: the auto white level (a few highlights clip)


@dataclass(frozen=True)
class PreviewRequest:
    """How the preview's white level is chosen: ``white_level`` (balanced linear value shown
    as white) or None for the image's own; ``source`` says where it came from."""

    white_level: float | None = None
    source: str = "auto"


def white_balance(light: str, sensitivities: str) -> tuple[float, float, float]:
    """Per-channel gains that show a white surface under ``light`` as grey (G gain 1).

    Parameters
    ----------
    light
        The scene light's spectrum name (renderer.spectra.light_spectrum).
    sensitivities
        The camera's sensitivities (renderer.spectra.camera_sensitivities).

    Returns
    -------
    tuple of float
        (R, G, B) gains: G over each channel's response to the light reflected by a
        reflectance-1 surface, the integral of sensitivity times spectrum.
    """
    response = light_camera_rgb(light, sensitivities)
    if not np.all(response > 0):
        raise UserInputError("the camera sees no light of this spectrum in some channel", field="light.spectrum",
                             got=light)
    r, g, b = (float(response[1] / v) for v in response)
    return r, g, b


def white_level_of(sidecar: str | Path) -> float:
    """The preview white level another render used, from its sidecar (``RENDER.json``, or the
    ``RENDER.exr`` beside it)."""
    path = Path(sidecar)
    path = path.with_suffix(".json") if path.suffix.lower() == ".exr" else path
    try:
        record = json.loads(path.read_text())
        level = float(record["preview_settings"]["white_level"])
    except FileNotFoundError:
        raise UserInputError("no such render sidecar", file=path, expected="the .json a `workbench render` wrote") \
            from None
    except (ValueError, KeyError, TypeError):
        raise UserInputError("holds no preview white level", file=path, field="preview_settings.white_level",
                             expected="the sidecar of a render made by this version") from None
    if not (np.isfinite(level) and level > 0):
        raise UserInputError("holds no usable preview white level", file=path, field="preview_settings.white_level",
                             expected="a number > 0", got=level)
    return level


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve (IEC 61966-2-1) on values clipped to [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def write_preview(rgb: np.ndarray, path: Path, gains: tuple[float, float, float], request: PreviewRequest) -> dict:
    """Write the 8-bit PNG preview of linear camera RGB ``rgb``; returns the sidecar's
    ``preview_settings`` (the gains, the white level used and where it came from)."""
    balanced = rgb * np.asarray(gains)
    level = request.white_level
    if level is None:
        level = float(np.percentile(balanced, AUTO_PERCENTILE)) or 1.0
    shown = srgb_encode(balanced / level)
    if not cv2.imwrite(str(path), (shown[..., ::-1] * 255 + 0.5).astype(np.uint8)):
        raise OSError(f"cannot write {path}")
    return {"white_balance": list(gains), "white_level": level, "source": request.source,
            "transfer": "sRGB (IEC 61966-2-1)"}

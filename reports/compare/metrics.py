"""Error maps between the aligned photo and render, and their statistics per region.

* Relative error: |photo - render| / (render + eps), the channels' mean, eps = 1 % of the
  walls' median brightness (so dark pixels do not explode).
* CIEDE2000 ([CIE 142-2001]; colour-science's ``delta_E_CIE2000``) between the two images
  in a display space: linear sRGB through the report's display transform, scaled so that
  the walls' median luminance is 0.18 (mid grey), clipped to [0, 1], to CIELAB (D65).
* FLIP ([Andersson 2020]; HDR-FLIP, [Andersson 2021]; NVIDIA's ``flip-evaluator`` package) on
  the linear sRGB images with the photo as reference, when the package is installed.
"""

from __future__ import annotations

import numpy as np

RELATIVE_EPS_SHARE = 0.01
MID_GREY = 0.18
SRGB_TO_XYZ = np.array([[0.4124564, 0.3575761, 0.1804375], [0.2126729, 0.7151522, 0.0721750],
                        [0.0193339, 0.1191920, 0.9503041]])


def relative_error(photo: np.ndarray, render: np.ndarray, reference_level: float) -> np.ndarray:
    eps = RELATIVE_EPS_SHARE * max(reference_level, 1e-12)
    return (np.abs(photo - render) / (np.abs(render) + eps)).mean(axis=2).astype(np.float32)


def _lab(srgb_linear: np.ndarray) -> np.ndarray:
    import colour  # deferred: start-up time

    xyz = np.clip(srgb_linear, 0.0, 1.0) @ SRGB_TO_XYZ.T
    return colour.XYZ_to_Lab(xyz, colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"])


def ciede2000(photo_display: np.ndarray, render_display: np.ndarray, exposure: float) -> np.ndarray:
    """Delta E 2000 per pixel between two linear sRGB images, both scaled by ``exposure``."""
    import colour  # deferred: start-up time

    return np.asarray(colour.delta_E(_lab(photo_display * exposure), _lab(render_display * exposure),
                                     method="CIE 2000"), np.float32)


def flip(photo_display: np.ndarray, render_display: np.ndarray) -> tuple[np.ndarray | None, str]:
    """HDR-FLIP map (photo as reference), or None and why not."""
    try:
        import flip_evaluator  # an optional dependency: the report says when it is missing
    except ImportError:
        return None, "flip-evaluator is not installed (pip install flip-evaluator)"
    error_map, _mean, _parameters = flip_evaluator.evaluate(np.ascontiguousarray(photo_display, np.float32),
                                                           np.ascontiguousarray(render_display, np.float32), "HDR",
                                                           inputsRGB=False, applyMagma=False)
    return np.asarray(error_map, np.float32).reshape(photo_display.shape[:2]), "HDR-FLIP, photo as reference"


def region_statistics(maps: dict[str, np.ndarray], masks: dict[str, np.ndarray]) -> dict[str, dict]:
    """Per region (and 'all'): mean, median and 95th percentile of each map, and the pixel count."""
    regions = dict(masks)
    regions["all"] = np.ones(next(iter(maps.values())).shape, bool)
    out: dict[str, dict] = {}
    for name, mask in regions.items():
        entry: dict = {"pixels": int(mask.sum())}
        for metric, values in maps.items():
            v = values[mask]
            v = v[np.isfinite(v)]
            entry[metric] = ({"mean": float(v.mean()), "median": float(np.median(v)), "p95": float(np.percentile(v, 95))}
                             if len(v) else None)
        out[name] = entry
    return out

"""Photo against render per region, as a statistical test: a z-score and consistent or not.

Per region (reports.compare.images.region_masks: walls, floor, ceiling, cd, glass, light) the
photo's mean and the render's mean are compared over the same pixels, at the exposure the
calibration fitted (the render as written, in the photo's units: no photometric scale
here, which would make the walls agree by construction). The difference D of the channel
sums of the means has variance, from every source that differs between the two:

* the photo's noise, from the photo itself (reports.compare.photo_noise), per channel the larger
  of: its sensor model (var = shot * x + read per raw site, summed over the region's sites
  / N^2), and the region's own mean squared second difference / N (what the photo carries
  beyond the sensor: a synthetic photo's render noise, or the region's texture, which can
  only widen the test);
* the render's Monte Carlo noise: the variance of its mean from the spread between its
  passes (renderer.render.variance_path), summed likewise; without that file (a render of
  one pass, or from elsewhere) this term is unknown and the row says so. Passes of few
  samples miss rare light paths, and then both the mean and its spread come out low: at
  16 spp the glass (caustics through the CD's top) was 9.7 % darker than the photo of the
  same camera, at z 4.9, and 0.6 % at 64 spp; below TRUSTED_SPP the result says so;
* the calibration's uncertainty through the prediction: the exposure's relative standard
  deviation times the render's mean, and the pose's, through the region itself: a pixel
  counts only where every camera drawn within the calibration's standard deviations
  (reports.fringes.prediction_band) sees the same region (and away from its border by BORDER_PX,
  for the lens's blur).

z = D / sqrt(var); a region is consistent when |z| <= Z_CONSISTENT (5). Raw photos are compared
on their own sites (each site's channel, no demosaicing, so sites are independent); other
photos on every pixel of each channel. Clipped photo pixels, and pixels the render puts at
or above the photo's clip level, are left out.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration.calibration_file import exposure_relative_std
from renderer.render import described_render, variance_path
from reports.compare.images import read_linear, region_masks
from reports.compare.photo_noise import NoiseModel, fit_noise, second_differences
from reports.fringes.prediction_band import draw_cameras

# Two-sided 5.7e-7 per region under the stated noise (a physicist's five sigma): a report's six to eight regions
# stay near 4e-6 flagged by chance, with room for the noise estimates' own error (3 degrees of freedom per render
# pixel, heavy-tailed paths); a 5 % exposure error puts the walls at z of about -100
Z_CONSISTENT = 5.0
BORDER_PX = 2
MIN_PIXELS = 100


@dataclass(frozen=True)
class RegionInputs:
    """What the comparison needs beside the images: the masks agreed by every drawn camera."""

    masks: dict[str, np.ndarray]
    exposure_rel_std: float | None  # None: the calibration states none
    camera_draws: int  # 0: the region masks of the fitted camera only


def stable_masks(fitted: dict[str, np.ndarray], drawn: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Per region, the pixels every camera (fitted and drawn) assigns to it, eroded by BORDER_PX."""
    kernel = np.ones((2 * BORDER_PX + 1, 2 * BORDER_PX + 1), np.uint8)
    out = {}
    for name, mask in fitted.items():
        agreed = mask.copy()
        for masks in drawn:
            agreed &= masks.get(name, np.zeros_like(mask))
        out[name] = cv2.erode(agreed.astype(np.uint8), kernel) > 0
    return out


def _sums(values: np.ndarray, use: np.ndarray, channel: np.ndarray | None) -> np.ndarray:
    """Per channel, the sum over ``use`` of (H, W, 3) ``values`` (raw: each site's own channel)."""
    if channel is None:
        return np.array([values[..., c][use].sum(dtype=np.float64) for c in range(3)])
    site = np.take_along_axis(values, channel[..., None], axis=2)[..., 0]
    return np.array([site[use & (channel == c)].sum(dtype=np.float64) for c in range(3)])


def _counts(use: np.ndarray, channel: np.ndarray | None) -> np.ndarray:
    if channel is None:
        return np.full(3, float(use.sum()))
    return np.array([float((use & (channel == c)).sum()) for c in range(3)])


def _local_variance(squared: np.ndarray, use: np.ndarray, channel: np.ndarray | None) -> np.ndarray:
    """Per channel, the mean squared second difference over ``use`` (photo_noise.second_differences)."""
    if channel is None:
        parts = [squared[..., c][use & np.isfinite(squared[..., c])] for c in range(3)]
    else:
        parts = [squared[use & (channel == c) & np.isfinite(squared)] for c in range(3)]
    return np.array([p.mean() if len(p) else np.nan for p in parts])


def _photo_variance(squared: np.ndarray, sensor_var: np.ndarray | None, use: np.ndarray, channel: np.ndarray | None,
                    n: np.ndarray) -> float:
    """The variance of the channel sum of the photo's region mean (module docstring)."""
    local = _local_variance(squared, use, channel) / n
    model = _sums(sensor_var, use, channel) / n**2 if sensor_var is not None else np.zeros(3)
    return float(np.sum(np.fmax(local, model)))


def compare_region(photo_rgb: np.ndarray, squared: np.ndarray, sensor_var: np.ndarray | None, render: np.ndarray,
                   render_var: np.ndarray | None, use: np.ndarray, channel: np.ndarray | None,
                   exposure_rel_std: float | None) -> dict:
    """One region's row (module docstring); ``squared``: the photo's squared second differences,
    ``sensor_var``: its sensor model's variance per pixel (None without a model)."""
    n = _counts(use, channel)
    if n.min() < MIN_PIXELS:
        return {"pixels": int(n.sum()), "status": f"fewer than {MIN_PIXELS} usable pixels per channel"}
    photo_mean, render_mean = _sums(photo_rgb, use, channel) / n, _sums(render, use, channel) / n
    terms = {"photo noise": _photo_variance(squared, sensor_var, use, channel, n),
             "render noise": float(np.sum(_sums(render_var, use, channel) / n**2)) if render_var is not None else None,
             "exposure": float((exposure_rel_std * render_mean.sum()) ** 2) if exposure_rel_std is not None else None}
    variance = sum(v for v in terms.values() if v is not None)
    difference = float(photo_mean.sum() - render_mean.sum())
    z = difference / np.sqrt(variance) if variance > 0 else float("inf") * np.sign(difference)
    unknown = [k for k, v in terms.items() if v is None]
    return {"pixels": int(n.sum()), "photo_mean": photo_mean.tolist(), "render_mean": render_mean.tolist(),
            "photo_minus_render": difference, "relative": difference / float(render_mean.sum()),
            "std": {k: (float(np.sqrt(v)) if v is not None else None) for k, v in terms.items()},
            "z": float(z), "consistent": bool(abs(z) <= Z_CONSISTENT),
            "status": "compared" + (f" (not stated: {', '.join(unknown)})" if unknown else "")}


def compare_regions(photo_rgb: np.ndarray, clipped: np.ndarray, channel: np.ndarray | None, clip_level: float | None,
                    render: np.ndarray, render_var: np.ndarray | None, inputs: RegionInputs,
                    noise: NoiseModel | None) -> dict:
    """Every region's row, and how the test was set (report.json's ``region_test``)."""
    usable = ~clipped
    if clip_level is not None:
        usable &= render.max(axis=2) < clip_level
    _level, diff, _cut = second_differences(photo_rgb, ~clipped, channel)
    squared, sensor_var = diff**2, noise.variance(photo_rgb) if noise else None  # once, for every region
    rows = {name: compare_region(photo_rgb, squared, sensor_var, render, render_var, mask & usable, channel,
                                 inputs.exposure_rel_std)
            for name, mask in inputs.masks.items()}
    return {"regions": rows, "z_consistent": Z_CONSISTENT, "border_px": BORDER_PX, "camera_draws": inputs.camera_draws,
            "photo_noise": noise.to_json() if noise else None, "exposure_rel_std": inputs.exposure_rel_std,
            "render_noise": "variance between the render's passes" if render_var is not None else None,
            "how": "channel sums of the region means at the calibrated exposure; z = difference / its std from the "
                   "photo's sensor noise, the render's pass variance and the exposure's std (reports.compare.regions)"}


REGION_DRAWS = 8  # cameras drawn for the stable masks (about 0.25 s each at 640 x 480)
TRUSTED_SPP = 64  # below it the per-pass variance misses rare paths (the caveat's measurement)


def render_variance(render_path: Path) -> tuple[np.ndarray | None, int | None]:
    """The render's pass variance (renderer.render.variance_path) and spp, where its sidecar
    describes this very EXR (renderer.render.described_render); (None, spp or None) otherwise."""
    info = described_render(render_path)
    if info is None:
        return None, None
    spp = info.get("spp") if isinstance(info.get("spp"), int) else None
    variance = variance_path(render_path)
    if not info.get("variance") or not variance.is_file():
        return None, spp
    return read_linear(variance, "the render's variance"), spp


def region_test(spec, fitted, photo, render: np.ndarray, render_path: Path, calibration: Path,
                masks: dict[str, np.ndarray], falloff: np.ndarray | None = None) -> dict:
    """report.json's ``region_test`` for ``photo`` (reports.compare.images.Photo, as taken) against the
    render as written: stable masks over REGION_DRAWS drawn cameras, the photo's noise model,
    the render's pass variance, the calibration's exposure std. ``falloff``: the lens's
    vignetting (calibration.intrinsics.vignetting) that ``render`` has been multiplied by, so its pass
    variance is too."""
    cameras = draw_cameras(fitted.model, fitted.std, REGION_DRAWS) if fitted.std else []
    drawn = [region_masks(spec, camera) for camera in cameras]
    inputs = RegionInputs(stable_masks(masks, drawn), exposure_relative_std(calibration, fitted.pose_key), len(drawn))
    variance, spp = render_variance(render_path)
    if variance is not None and falloff is not None:
        variance = variance * falloff**2
    out = compare_regions(photo.rgb, photo.clipped, photo.channel, photo.clip_level, render, variance, inputs,
                          fit_noise(photo.rgb, photo.clipped, photo.channel))
    out["render_spp"] = spp
    if spp is not None and spp < TRUSTED_SPP:
        out["caveat"] = (f"the render has {spp} spp: below {TRUSTED_SPP}, regions lit along rare paths (caustics through "
                         "the CD's top) can come out darker than their expectation by more than the passes' spread "
                         "shows (measured: the glass 9.7 % low at 16 spp, 0.6 % at 64); a flag there is worth a render "
                         f"of {TRUSTED_SPP} spp or more before it is believed")
    return out

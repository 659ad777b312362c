"""The CD's colour fringes by hue: where the equivalent wavelength passes 440, 460, ... nm.

Hue crossings (the second measure, issue 15): the camera's hue, white-balanced on the light,
turned into an equivalent wavelength with the camera's spectral sensitivities (HueScale:
the hue angle of monochromatic light, over the wavelengths the camera tells apart), and
the places along each circle where it passes 440, 460, ... nm inside an order's band
(find_hue_crossings), with their own quality flags. A pixel of a band receives some 300 nm
at once, so its equivalent wavelength is its light's dominant one, not one it receives alone.

The crossings are located on the profiles and bands of reports.fringes.band_edges (the same polar
grids, the same predicted bands, the same noise measure) and are Edges, so photo, render
and prediction pair as band edges do (reports.fringes.band_edges.pair_edges).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from reports.fringes.band_edges import (
    EDGE_SIGMA_MAX_PX,
    HOLD_PX,
    LIT_THRESHOLD,
    MIN_BAND_LIT,
    NOISE_CORRELATION_PX,
    OTHER_ORDER_LIT,
    OTHER_ORDER_SHARE,
    RAMP_REACH_PX,
    Band,
    Edge,
    profile_noise,
    sampled_profiles,
    seam,
    true_runs,
)
from reports.fringes.polar import PolarGrid

HUE_LEVELS_NM = tuple(range(440, 661, 20))  # equivalent wavelengths whose crossings are located
HUE_MIN_SATURATION = 0.08  # white-balanced chromaticity's distance from white below which hue is not measurable
HUE_LOCUS_MIN_SATURATION = 0.2  # the spectral locus is used where monochromatic light is at least this saturated
HUE_MIN_TURN_DEG = 0.5  # wavelengths 5 nm apart whose hues differ by less are not told apart
HUE_SMOOTH_PX = 1.0  # the equivalent wavelength is averaged over this (Gaussian sigma) along the profile
HUE_MIN_SIGNAL = 0.25  # the band's signal (above background) over its maximum below which hue is not measured
HUE_SIGMA_MAX_PX = EDGE_SIGMA_MAX_PX  # the same rule as the band edges
ANGLE_ROUND_OFF = 1e-9  # radians: a hue at the scale's end computed twice differs by round-off


@dataclass(frozen=True)
class HueScale:
    """Camera hue to equivalent wavelength: the hue angle of monochromatic light, over the
    part of the spectrum where it turns monotonically (the camera tells wavelengths apart)."""

    wavelengths_nm: np.ndarray
    angles: np.ndarray  # increasing, unwrapped (radians), times ``sign``
    white: np.ndarray  # (3,) the camera RGB of the light (white balance)
    sign: float = 1.0  # the way hue turns with wavelength

    def wavelength(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(equivalent wavelength in nm, saturation) of linear camera RGB (..., 3); nan where the
        hue lies off the scale (purples: red and blue together, which no one wavelength gives)."""
        angle, saturation = hue_angle(rgb, self.white)
        angle = self.sign * angle
        lo, hi = self.angles[0], self.angles[-1]
        angle = lo + np.mod(angle - lo + ANGLE_ROUND_OFF, 2 * np.pi) - ANGLE_ROUND_OFF
        angle = np.where((angle > hi) & (angle <= hi + ANGLE_ROUND_OFF), hi, angle)  # the scale's ends, to round-off
        nm = np.interp(angle, self.angles, self.wavelengths_nm, left=np.nan, right=np.nan)
        return nm, saturation


def hue_angle(rgb: np.ndarray, white: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hue angle (radians) and saturation of camera RGB white-balanced on ``white``: the
    chromaticity b / sum(b) (b = rgb / white) in an opponent plane, (R - G) / sqrt 2 and
    (R + G - 2 B) / sqrt 6, about the white point (1/3, 1/3, 1/3)."""
    b = np.asarray(rgb, float) / np.asarray(white, float)
    total = b.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        x = b / total[..., None]
    a1 = (x[..., 0] - x[..., 1]) / np.sqrt(2.0)
    a2 = (x[..., 0] + x[..., 1] - 2.0 * x[..., 2]) / np.sqrt(6.0)
    saturation = np.where(total > 0, np.hypot(a1, a2), np.nan)
    return np.arctan2(a2, a1), saturation


def hue_scale(wavelengths_nm: np.ndarray, weights: np.ndarray, white: np.ndarray) -> HueScale:
    """The scale from the camera's channel weights S_c E normalised per channel (renderer.trace.prediction.
    channel_weights: monochromatic light at lambda, white-balanced on the light, is ``weights[:, lambda]``)
    and the light's camera RGB ``white``. From the shortest wavelength on, a wavelength joins
    the scale when its monochromatic hue is at least ``HUE_LOCUS_MIN_SATURATION`` saturated and
    has turned on by ``HUE_MIN_TURN_DEG`` past the last one kept: where the hue stands still
    (a camera whose channels do not overlap there) wavelengths cannot be told apart by hue."""
    angle, saturation = hue_angle(weights.T * white[None], white)
    angle = np.unwrap(angle)
    sign = 1.0 if angle[-1] >= angle[0] else -1.0
    angle = sign * angle
    keep: list[int] = []
    for k in range(len(angle)):
        if saturation[k] < HUE_LOCUS_MIN_SATURATION:
            continue
        if not keep or angle[k] > angle[keep[-1]] + np.radians(HUE_MIN_TURN_DEG):
            keep.append(k)
    if len(keep) < 2:
        raise ValueError("the camera's hue does not change with wavelength: no hue scale")
    angles = angle[keep]
    return HueScale(np.asarray(wavelengths_nm, float)[keep], angles, np.asarray(white, float), sign)


def _smooth_where(values: np.ndarray, usable: np.ndarray, sigma_samples: float) -> np.ndarray:
    """Gaussian smoothing over the usable samples only (normalised convolution); nan elsewhere."""
    weight = usable.astype(float)
    filled = np.where(usable, values, 0.0)
    top = gaussian_filter1d(filled, sigma_samples, mode="nearest")
    bottom = gaussian_filter1d(weight, sigma_samples, mode="nearest")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(usable & (bottom > 0), top / bottom, np.nan)


def _level_crossings(nm: np.ndarray, usable: np.ndarray, level: float, first: int, last: int) -> list[float]:
    """Fractional positions in [first, last] where ``nm`` passes ``level`` between usable samples."""
    found = []
    for k in range(first, last):
        if usable[k] and usable[k + 1]:
            a, b = nm[k] - level, nm[k + 1] - level
            if a == 0 or a * b < 0:
                found.append(k + (a / (a - b) if a != b else 0.0))
    return found


def _hue_position(nm: np.ndarray, usable: np.ndarray, crossing: float, level: float, px: float) -> tuple[float, float, int]:
    """The crossing refined by a line fitted to nm within ``RAMP_REACH_PX``: (position, |slope| per sample, samples)."""
    reach = int(np.ceil(RAMP_REACH_PX / max(px, 1e-6)))
    centre = int(round(crossing))
    idx = np.arange(max(centre - reach, 0), min(centre + reach, len(nm) - 1) + 1)
    idx = idx[usable[idx]]
    if len(idx) < 3:
        return crossing, float("nan"), len(idx)
    slope, intercept = np.polyfit(idx.astype(float), nm[idx], 1)
    position = (level - intercept) / slope if slope != 0 else crossing
    if not idx[0] - 1.0 <= position <= idx[-1] + 1.0:
        position = crossing
    return float(position), float(abs(slope)), len(idx)


def _above_background(rgb: np.ndarray, lit_any: np.ndarray) -> np.ndarray:
    """A profile (3, n) minus its background: per channel, the median where no order is predicted lit."""
    dark = ~lit_any & np.isfinite(rgb).all(axis=0)
    background = np.median(rgb[:, dark], axis=1) if dark.any() else np.nanmin(rgb, axis=1)
    return rgb - background[:, None]


def _band_hue_crossings(signal: np.ndarray, band: Band, total: np.ndarray, scale: HueScale, clip_row: np.ndarray | None,
                        step: np.ndarray, correlation_px: float, levels: tuple[int, ...], measured: bool) -> list[tuple]:
    """The hue crossings of one order's band (find_hue_crossings): (level, position, sigma_px,
    saturation, slope over noise, quality) for each level passed. ``signal`` (3, n) above the
    background; ``total`` (orders, n) every order's predicted lit fraction; ``measured``: an
    image (its noise is measured) rather than the prediction."""
    i, first, last = band.order_index, band.start, band.stop
    mean_step = float(np.nanmean(step)) if np.any(np.isfinite(step)) else 1.0
    nm, saturation = scale.wavelength(np.moveaxis(signal, 0, -1))
    strength = (signal / scale.white[:, None]).sum(axis=0)
    peak = np.nanmax(strength[first:last + 1])
    usable = np.isfinite(nm) & (saturation >= HUE_MIN_SATURATION) & (strength >= HUE_MIN_SIGNAL * peak)
    usable[:first] = False
    usable[last + 1:] = False
    if clip_row is not None:
        usable &= ~clip_row  # a saturated pixel's hue is not its light's
    noise = profile_noise(np.where(usable, nm, np.nan), band, max(2 * int(np.ceil(HOLD_PX / max(mean_step, 1e-6))), 1)) \
        if measured else 0.0
    others = np.delete(total[:, first:last + 1], i, axis=0)
    overlapping = bool(others.size) and float(others.max()) > max(OTHER_ORDER_SHARE * total[i].max(), OTHER_ORDER_LIT)
    nm = _smooth_where(nm, usable, HUE_SMOOTH_PX / max(mean_step, 1e-6))
    out = []
    for level in levels:
        found = _level_crossings(nm, usable, float(level), first, last)
        if not found:
            continue
        crossing = float(np.median(found))
        spread_px = (max(found) - min(found)) * mean_step
        px = float(step[int(round(crossing))]) if np.isfinite(step[int(round(crossing))]) else mean_step
        position, slope, samples = _hue_position(nm, usable, crossing, float(level), px)
        independent = max(1.0, samples * px / correlation_px)
        sigma_px = noise / slope * px / np.sqrt(independent) if slope > 0 else float("inf")
        quality = ("ambiguous" if spread_px > 2 * RAMP_REACH_PX else "overlap" if overlapping else
                   "weak" if not sigma_px <= HUE_SIGMA_MAX_PX else "ok")
        out.append((level, position, float(sigma_px), float(saturation[int(round(position)) % len(nm)]),
                    float(slope / noise) if noise > 0 else float("inf"), quality))
    return out


def find_hue_crossings(polar: PolarGrid, pred_samples: np.ndarray, orders: list[int], scale: HueScale,
                       image: np.ndarray | None = None, correlation_px: float = NOISE_CORRELATION_PX,
                       levels: tuple[int, ...] = HUE_LEVELS_NM, clipped: np.ndarray | None = None) -> list[Edge]:
    """Where the equivalent wavelength (HueScale) passes each of ``levels`` inside each order's
    predicted band, along every profile of ``polar``: Edges with channel ``hue`` and side
    ``"<level> nm"`` (so photo, render and prediction pair as band edges do). Meant for the
    circle grid: along a circle the hue changes fast (about 8-17 nm per pixel on
    cornell_cd_view2 at 640 x 480 and 320 x 240) and the median across the profile runs along
    the radius, where it changes about 0.5 nm per pixel; along a radius it is the other way
    round (measured: 0.15 px median from the known wavelength along circles, 0.9 px along radii).

    The image's signal is its profile minus the background (the median of the window where no
    order is predicted lit, per channel); for the prediction (``image`` None) the lit fractions
    times the light's white. Hue is measurable where the signal is at least ``HUE_MIN_SIGNAL``
    of the band's maximum, ``HUE_MIN_SATURATION`` saturated and not ``clipped``; the wavelength is then averaged over
    ``HUE_SMOOTH_PX``. Quality: ``ambiguous`` (the level is passed at places more than 2
    ``RAMP_REACH_PX`` apart), ``overlap`` (another order lit there),
    ``weak`` (position uncertainty, wavelength noise / (slope sqrt(N)), over ``HUE_SIGMA_MAX_PX``),
    else ``ok``."""
    periodic, pred, _, values, clip, steps = sampled_profiles(polar, pred_samples, image, clipped)
    edges: list[Edge] = []
    n = pred.shape[-1]
    for p in range(polar.profile_count):
        roll = seam(pred[:, :, p].sum(axis=(0, 1))) if periodic else 0
        lit = np.roll(np.nan_to_num(pred[:, :, p]), -roll, axis=-1)  # (orders, 3, n)
        step = np.roll(steps[p], -roll)
        total = lit.sum(axis=1)  # (orders, n)
        lit_any = (total > np.maximum(LIT_THRESHOLD * total.max(axis=1, keepdims=True), OTHER_ORDER_LIT)).any(axis=0)
        rgb = None if image is None else np.roll(values[:, p], -roll, axis=-1)
        clip_row = np.roll(clip[p], -roll) if clip is not None else None
        for i in range(len(orders)):
            if not total[i].max() > 0:
                continue
            for number, (first, last) in enumerate(true_runs(total[i] > LIT_THRESHOLD * total[i].max())):
                if total[i, first:last + 1].max() < 3 * MIN_BAND_LIT:
                    continue
                band = Band(i, 0, int(first), int(last), number)
                signal = lit[i] * scale.white[:, None] if rgb is None else _above_background(rgb, lit_any)
                for level, position, sigma_px, sat, snr, quality in _band_hue_crossings(
                        signal, band, total, scale, clip_row, step, correlation_px, levels, rgb is not None):
                    original = (position + roll) % n if periodic else position
                    xy = polar.point(p, original)
                    edges.append(Edge(polar.kind, p, polar.profile_label(p), orders[i], "hue", number, f"{level} nm",
                                      float(original), polar.coordinate(original), float(xy[0]), float(xy[1]),
                                      sigma_px, sat, snr, quality))
    return edges

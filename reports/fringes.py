"""The CD's colour fringes measured in an image: its rim, and the edges of each order's lit band.

What a pixel sees (issue 15): the ceiling light spans about +-7 deg from the CD, so a
pixel of a diffracted band receives some 300 nm of spectrum and colour changes only
about 0.5 nm per pixel along a radius. The sharp, comparable features are the edges of
each order's lit band: where a colour channel's brightness crosses half its band maximum
(above the local background), along circles about the CD's centre and along radii.

How (per image: photo, render, or the prediction of reports.prediction):

* Profiles: the image is sampled on the polar grids of reports.polar (the same pixel
  positions for every image) and smoothed by [1, 2, 1] / 4 along the profile.
* Bands: the prediction says, per profile, order and channel, where the band is (its lit
  fraction above ``LIT_THRESHOLD`` of its maximum there); a band whose peak lit fraction
  is below ``MIN_BAND_LIT`` is too dim in that channel to use.
* Edges: in the image, the band's window (the predicted band widened by
  ``WINDOW_EXTENSION_PX`` on each side) gives the peak; the background is the median of
  the window where no order is predicted lit; the band's maximum is a high percentile of
  the profile smoothed over ``TOP_SMOOTH_PX`` (so that noise does not raise it: a noisier
  image would otherwise put its half level higher and its edges inward); the half level is
  the mean of background and maximum. From the peak outward the first crossing of the half
  level (it must hold for ``HOLD_PX``) locates the edge; the edge's position is then a
  straight line fitted to the whole ramp around it (the samples between ``RAMP_LEVELS`` of
  the contrast, within ``RAMP_REACH_PX``) and crossed with the half level. The prediction's
  own edges are found the same way on its lit fraction (background 0).
* Quality: ``missing`` (no crossing inside the window), ``overlap`` (another order's band
  reaches into the window: the edge is ambiguous), ``weak`` (contrast under ``SNR_MIN``
  noise sigmas or under ``MIN_RELATIVE_CONTRAST`` of the background, or the edge's position
  uncertainty over ``EDGE_SIGMA_MAX_PX``), ``clipped`` (otherwise fine, but saturated photo
  pixels in the band: the half level is not half the band's maximum, so the edge is not
  compared with the prediction; it is compared with a render passed through the photo's
  own saturation, reports.images.through_photo_sensor), else ``ok``.

Why this quality rule (measured on cornell_cd_view2 at 640 x 480: a 64 spp synthetic
photo against a 256 spp render): the large photo-render offsets came from gentle edges
(a channel's band that ramps over several pixels, e.g. the red end of a blue-rich order)
in the noisy photo: there one pixel's Monte Carlo noise moves a two-sample crossing by
a pixel or more. The ramp fit averages the noise over the ramp's pixels, and the rule
asks of every edge what the comparison needs: its position uncertainty, sigma_px =
noise / (slope sqrt(N)), with the noise measured on the profile itself (the robust spread
of second differences two pixels apart, inside the band), the slope that of the fitted
ramp (per pixel) and N the ramp's length in pixels (samples closer than
``NOISE_CORRELATION_PX`` share their pixels' noise), must be small enough that two such
edges' 95 % interval stays under the 1.5 px bar (``EDGE_SIGMA_MAX_PX``). An edge that
fails is not dropped from the CSV: it is flagged ``weak`` and left out of the offsets.

Hue crossings (the second measure, issue 15): the camera's hue, white-balanced on the light,
turned into an equivalent wavelength with the camera's spectral sensitivities (HueScale:
the hue angle of monochromatic light, over the wavelengths the camera tells apart), and
the places along each circle where it passes 440, 460, ... nm inside an order's band
(find_hue_crossings), with their own quality flags. A pixel of a band receives some 300 nm
at once, so its equivalent wavelength is its light's dominant one, not one it receives alone.

The rim: edges of the CD's disk are found along normals of the expected rim (the camera's
projection of the rim circle), at the strongest brightness gradient (parabolic sub-pixel
peak), and an ellipse is fitted to them (cv2.fitEllipse, outliers over
``RIM_OUTLIER_PX`` dropped), so a photo's CD is located from the photo itself and a
wrong pose shows up as an offset.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter1d

from reports.polar import PolarGrid, sample

SMOOTH_KERNEL = np.array([0.25, 0.5, 0.25])
LIT_THRESHOLD = 0.02  # fraction of the band's own maximum where the predicted band starts
OTHER_ORDER_LIT = 0.01  # lit fractions below this (1 % of the light) count as dark
OTHER_ORDER_SHARE = 0.1  # another order lit in the same channel above this share of the band's peak: an ambiguous edge
MIN_BAND_LIT = 0.08  # a channel whose predicted lit fraction peaks below this sees too little of the band
WINDOW_EXTENSION_PX = 6.0  # an image's edge may lie this far outside the predicted band and still be found
PEAK_PERCENTILE = 90.0  # the band's maximum, robust to outliers
HOLD_PX = 1.0  # a crossing counts when the profile stays beyond it for this long
SNR_MIN = 6.0  # contrast over noise sigma below which an edge is weak
MIN_RELATIVE_CONTRAST = 0.25  # a band of the light is far brighter than the CD's wall-lit background (10-30x here)
EDGE_SIGMA_MAX_PX = 0.35  # an edge's position uncertainty over this is weak: two such edges differ by
# sqrt(2) 0.35 = 0.5 px (one sigma), so a pair's 95 % interval (1 px) stays under the p95 bar of 1.5 px
RAMP_LEVELS = (0.2, 0.8)  # the edge's ramp: where the profile lies between these fractions of the band's contrast
RAMP_REACH_PX = 2.5  # the ramp fit uses samples at most this far from the first crossing
NOISE_CORRELATION_PX = 1.0  # profile samples closer than a pixel share their pixels' noise (bilinear sampling)
CLIPPED_NOISE_SHARE = 0.8  # in a saturated band the noise is measured on samples below this share of the contrast
MOSAIC_CORRELATION_PX = 2.0  # a raw photo's channel is sampled every 2 px of its Bayer mosaic and demosaiced
# bilinearly: its noise is shared over 2 px
TOP_SMOOTH_PX = 1.0  # the band's maximum is read on the profile smoothed by a Gaussian of this sigma
MAD_TO_SIGMA = 1.4826
RIM_SEARCH_PX = 8.0  # how far from the expected rim the photo's rim is looked for
RIM_NORMALS = 360
RIM_OUTLIER_PX = 1.5
RIM_MIN_POINTS = 24
CHANNELS = ("R", "G", "B")


@dataclass
class Edge:
    """One band edge found in one image (positions in samples along the profile)."""

    kind: str  # "circle" or "radius"
    profile: int
    label: float  # rho (circle) or azimuth in degrees (radius)
    order: int
    channel: str
    band: int  # the band's number along this profile (for this order and channel)
    side: str  # "start" or "end": where the band begins or ends along the profile
    position: float
    coordinate: float  # azimuth in degrees (circle) or rho (radius)
    x: float
    y: float
    sigma_px: float
    contrast: float
    snr: float
    quality: str

    def key(self) -> tuple:
        return (self.kind, self.profile, self.order, self.channel, self.band, self.side)

    def to_json(self) -> dict:
        return asdict(self)


@dataclass
class _Band:
    order_index: int
    channel: int
    start: int  # first lit sample (unrolled indices)
    stop: int  # last lit sample
    number: int


def smooth(profile: np.ndarray, periodic: bool) -> np.ndarray:
    """[1, 2, 1] / 4 along the last axis (wrapping for periodic profiles; ends kept)."""
    if periodic:
        return 0.25 * np.roll(profile, 1, -1) + 0.5 * profile + 0.25 * np.roll(profile, -1, -1)
    out = profile.copy()
    out[..., 1:-1] = 0.25 * profile[..., :-2] + 0.5 * profile[..., 1:-1] + 0.25 * profile[..., 2:]
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) of each run of True."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(padded)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1, strict=True))


def _bands(pred: np.ndarray) -> list[_Band]:
    """The predicted bands of one profile: pred (orders, 3, n) lit fractions (unrolled)."""
    out = []
    for i in range(pred.shape[0]):
        for c in range(3):
            line = pred[i, c]
            top = np.nanmax(line) if np.any(np.isfinite(line)) else 0.0
            if not top > 0:
                continue
            number = 0
            for first, last in _runs(np.nan_to_num(line) > LIT_THRESHOLD * top):
                if np.nanmax(line[first:last + 1]) >= MIN_BAND_LIT:
                    out.append(_Band(i, c, int(first), int(last), number))
                    number += 1
    return out


def _crossing(values: np.ndarray, peak: int, level: float, step: int, limit: int, hold: int) -> float | None:
    """Fractional index where ``values`` falls to ``level`` going from ``peak`` by ``step``
    (within ``limit``) and stays below it for ``hold`` more samples (or to the limit): a
    dip of noise inside the band is passed over. Linear interpolation at the crossing."""
    j = peak
    while True:
        k = j + step
        if (step < 0 and k < limit) or (step > 0 and k > limit):
            return None
        if not np.isfinite(values[k]):
            return None
        if values[k] <= level:
            following = k + step * np.arange(hold + 1)
            after = values[following[(following >= 0) & (following < len(values))]]
            if np.all(after[np.isfinite(after)] <= level):
                a, b = values[j], values[k]
                t = (a - level) / (a - b) if a != b else 0.5
                return j + step * t
        j = k


def _band_top(line: np.ndarray, band: _Band, smooth_samples: float) -> float:
    """The band's maximum: the ``PEAK_PERCENTILE`` percentile inside the band of the profile
    smoothed by a Gaussian of ``smooth_samples`` (a percentile of noisy samples sits above the
    signal's by about a noise sigma; smoothing over a pixel or so takes most of that away)."""
    inside = line[band.start:band.stop + 1]
    if len(inside) < 4:
        return float(np.nanmax(inside))
    finite = np.isfinite(line)
    if smooth_samples > 0 and finite.all():
        inside = gaussian_filter1d(line, smooth_samples, mode="nearest")[band.start:band.stop + 1]
    return float(np.nanpercentile(inside, PEAK_PERCENTILE))


def _ramp_fit(line: np.ndarray, position: float, background: float, contrast: float, level: float, direction: int,
              px: float) -> tuple[float, float, int] | None:
    """The edge's position from a straight line fitted to its ramp: the samples next to the
    first crossing ``position`` (going outward by ``direction``) whose values lie between
    ``RAMP_LEVELS`` of the contrast above ``background``, within ``RAMP_REACH_PX``. Returns
    (position where the line meets ``level``, |slope| per sample, samples used), or None
    when the ramp has fewer than three samples or the fit falls the wrong way."""
    n = len(line)
    low, high = background + RAMP_LEVELS[0] * contrast, background + RAMP_LEVELS[1] * contrast
    reach = int(np.ceil(RAMP_REACH_PX / max(px, 1e-6)))
    centre = int(np.clip(round(position), 0, n - 1))
    chosen = [centre] if low <= line[centre] <= high else []
    for way in (-1, 1):
        k = centre + way
        while 0 <= k < n and abs(k - centre) <= reach and np.isfinite(line[k]) and low <= line[k] <= high:
            chosen.append(k)
            k += way
    if len(chosen) < 3:
        return None
    x = np.asarray(sorted(chosen), float)
    slope, intercept = np.polyfit(x, line[x.astype(int)], 1)
    if not slope * direction < 0:  # going outward the profile must fall
        return None
    crossing = (level - intercept) / slope
    if not x[0] - 1.0 <= crossing <= x[-1] + 1.0:
        return None
    return float(crossing), float(abs(slope)), len(x)


def _profile_noise(raw: np.ndarray, band: _Band, lag: int) -> float:
    """Noise sigma of a profile inside a band: the robust spread of second differences of
    samples ``lag`` apart (two pixels, so that interpolation and the median across the
    profile do not correlate them; a linear ramp of the signal cancels), over sqrt(6)."""
    segment = raw[band.start:band.stop + 1]
    if len(segment) < 2 * lag + 4:
        return float("inf")
    d = segment[2 * lag:] - 2.0 * segment[lag:-lag] + segment[:-2 * lag]
    d = d[np.isfinite(d)]  # only triples of samples that are all there (nan: outside the image, or left out)
    if len(d) < 4:
        return float("inf")
    return MAD_TO_SIGMA * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(6.0)


def _profile_edges(values: np.ndarray | None, raw: np.ndarray | None, clipped: np.ndarray | None, pred: np.ndarray,
                   step_px: np.ndarray, own_prediction: bool, correlation_px: float = NOISE_CORRELATION_PX,
                   ) -> list[tuple[_Band, str, float, float, float, float, str]]:
    """Edges of every predicted band in one profile (unrolled): (band, side, position,
    sigma_px, contrast, snr, quality). ``values`` (3, n) is the image's smoothed profile and
    ``raw`` the same before smoothing; for the prediction itself (``own_prediction``) the
    per-order lit fractions ``pred`` are used instead."""
    n = pred.shape[-1]
    lit = np.nan_to_num(pred)
    lit_anywhere = (lit.max(axis=1) > np.maximum(LIT_THRESHOLD * lit.max(axis=(1, 2))[:, None], OTHER_ORDER_LIT)).any(axis=0)
    mean_step = float(np.nanmean(step_px)) if np.any(np.isfinite(step_px)) else 1.0
    extension = int(np.ceil(WINDOW_EXTENSION_PX / max(mean_step, 1e-6)))
    hold = int(np.ceil(HOLD_PX / max(mean_step, 1e-6)))
    found = []
    for band in _bands(pred):
        line = pred[band.order_index, band.channel] if own_prediction or values is None else values[band.channel]
        w0, w1 = max(band.start - extension, 0), min(band.stop + extension, n - 1)
        window = line[w0:w1 + 1]
        if not np.any(np.isfinite(window)):
            continue
        inside = line[band.start:band.stop + 1]
        peak = band.start + int(np.nanargmax(inside))
        # the band's maximum as a high percentile (the same for images and prediction): one bright
        # outlier must not raise the half level
        top = _band_top(line, band, TOP_SMOOTH_PX / max(mean_step, 1e-6))
        if own_prediction:
            background = 0.0
        else:
            dark = ~lit_anywhere[w0:w1 + 1] & np.isfinite(window)
            background = float(np.median(window[dark])) if dark.any() else float(np.nanmin(window))
        contrast = top - background
        level = background + 0.5 * contrast
        band_peak = float(np.max(lit[band.order_index, band.channel, band.start:band.stop + 1]))
        others = np.delete(lit[:, band.channel, w0:w1 + 1], band.order_index, axis=0)
        overlapping = bool(others.size) and float(others.max()) > max(OTHER_ORDER_SHARE * band_peak, OTHER_ORDER_LIT)
        is_clipped = clipped is not None and bool(clipped[band.start:band.stop + 1].any())
        noisy = None if raw is None else raw[band.channel]
        where = band
        if noisy is not None and is_clipped:  # a saturated plateau has no noise: measure it below the plateau,
            # over the whole window (the band's ramps and the background beside them)
            noisy = np.where(noisy < background + CLIPPED_NOISE_SHARE * contrast, noisy, np.nan)
            where = _Band(band.order_index, band.channel, w0, w1, band.number)
        sigma = 0.0 if noisy is None else _profile_noise(noisy, where, max(2 * hold, 1))
        for side, direction, limit in (("start", -1, w0), ("end", 1, w1)):
            if (side == "start" and band.start == 0) or (side == "end" and band.stop == n - 1):
                continue  # the band runs past the profile's end (into the rim or the hole): no edge there
            position = _crossing(line, peak, level, direction, limit, hold) if contrast > 0 else None
            if position is None:
                found.append((band, side, float("nan"), float("nan"), contrast, float("nan"), "missing"))
                continue
            j = int(np.clip(round(position), 1, n - 2))
            px = float(step_px[j]) if np.isfinite(step_px[j]) else mean_step
            fitted = _ramp_fit(line, position, background, contrast, level, direction, px)
            if fitted is not None:
                position, slope, samples = fitted
            else:
                slope, samples = abs(line[min(j + 1, n - 1)] - line[max(j - 1, 0)]) / 2.0, 1  # per sample
            independent = max(1.0, samples * px / correlation_px)
            sigma_px = sigma / slope * px / np.sqrt(independent) if slope > 0 else float("inf")
            snr = contrast / sigma if sigma > 0 else float("inf")
            faint = not own_prediction and contrast < MIN_RELATIVE_CONTRAST * abs(background)
            quality = ("overlap" if overlapping else
                       "weak" if (snr < SNR_MIN or sigma_px > EDGE_SIGMA_MAX_PX or faint) else "clipped" if is_clipped else "ok")
            found.append((band, side, float(position), sigma_px, contrast, snr, quality))
    return found


def _seam(total: np.ndarray) -> int:
    """Where a circle is cut open: a sample where the predicted bands are dimmest."""
    return int(np.argmin(np.nan_to_num(total, nan=np.inf)))


def _sampled_profiles(polar: PolarGrid, pred_samples: np.ndarray, image: np.ndarray | None, clipped: np.ndarray | None):
    """The prediction and the image sampled along the grid's profiles, smoothed alike:
    (periodic, pred (orders, 3, profiles, n), raw and values (3, profiles, n) or None,
    clip (profiles, n) or None, steps (profiles, n) px)."""
    periodic = polar.kind == "circle"
    pred = smooth(np.moveaxis(pred_samples, 3 if periodic else 2, -1), periodic)
    raw = values = None
    if image is not None:
        raw = np.moveaxis(sample(image, polar, robust=True), (2, 1 if periodic else 0), (0, -1))
        values = smooth(raw, periodic)
    clip = (np.moveaxis(sample(clipped.astype(np.float32), polar), 1 if periodic else 0, -1) > 0
            if clipped is not None else None)
    steps = polar.step_px()
    return periodic, pred, raw, values, clip, (steps if periodic else steps.T)


def find_edges(polar: PolarGrid, pred_samples: np.ndarray, orders: list[int], image: np.ndarray | None = None,
               clipped: np.ndarray | None = None, correlation_px: float = NOISE_CORRELATION_PX) -> list[Edge]:
    """Band edges along every profile of ``polar``.

    ``pred_samples`` (orders, 3, radii, azimuths): the prediction sampled on the grid as the
    images are (reports.polar.sample with ``robust=True``), so that its own edges are comparable.
    ``image`` (H, W, 3) linear camera RGB; None measures the prediction's own edges.
    ``clipped`` (H, W) bool: saturated pixels. ``correlation_px``: the distance over which the
    image's noise is shared (``MOSAIC_CORRELATION_PX`` for a demosaiced raw photo).
    """
    periodic, pred, raw, values, clip, steps = _sampled_profiles(polar, pred_samples, image, clipped)
    edges: list[Edge] = []
    for p in range(polar.profile_count):
        roll = _seam(pred[:, :, p].sum(axis=(0, 1))) if periodic else 0
        unroll = (lambda a, r=roll: np.roll(a, -r, axis=-1))  # noqa: E731
        found = _profile_edges(unroll(values[:, p]) if image is not None else None,
                               unroll(raw[:, p]) if image is not None else None,
                               unroll(clip[p]) if image is not None and clip is not None else None,
                               unroll(pred[:, :, p]), unroll(steps[p]), own_prediction=image is None,
                               correlation_px=correlation_px)
        n = pred.shape[-1]
        for band, side, position, sigma_px, contrast, snr, quality in found:
            original = (position + roll) % n if periodic and np.isfinite(position) else position
            xy = polar.point(p, original) if np.isfinite(original) else np.array([np.nan, np.nan])
            edges.append(Edge(polar.kind, p, polar.profile_label(p), orders[band.order_index], CHANNELS[band.channel],
                              band.number, side, float(original),
                              polar.coordinate(original) if np.isfinite(original) else float("nan"),
                              float(xy[0]), float(xy[1]), float(sigma_px), float(contrast), float(snr), quality))
    return edges


@dataclass
class EdgePair:
    """The same edge in two images: its offset along the profile (b minus a), in px and degrees."""

    key: tuple
    a: Edge
    b: Edge
    offset_px: float
    offset_deg: float  # azimuth on the CD (circles) or the camera's visual angle (radii)


def _signed_offset(polar: PolarGrid, a: Edge, b: Edge) -> float:
    """The position of b minus that of a along the profile, in pixels (arc length through the grid)."""
    n = polar.pixels.shape[1] if polar.kind == "circle" else polar.pixels.shape[0]
    d = b.position - a.position
    if polar.kind == "circle":
        d = (d + n / 2) % n - n / 2
    distance = float(np.linalg.norm(np.array([b.x - a.x, b.y - a.y])))
    return float(np.sign(d) * distance)


def pair_edges(polar: PolarGrid, a: list[Edge], b: list[Edge], focal_px: float, *, require_ok: bool = True,
               accept: tuple[str, ...] = ("ok",)) -> list[EdgePair]:
    """Edges of ``a`` and ``b`` that are the same predicted edge, both found (and of a quality in
    ``accept`` when ``require_ok``: ``clipped`` too where both images saw the same saturation)."""
    by_key = {e.key(): e for e in b}
    pairs = []
    for ea in a:
        eb = by_key.get(ea.key())
        if eb is None or not (np.isfinite(ea.position) and np.isfinite(eb.position)):
            continue
        if require_ok and (ea.quality not in accept or eb.quality not in accept):
            continue
        px = _signed_offset(polar, ea, eb)
        if polar.kind == "circle":
            deg = (eb.coordinate - ea.coordinate + 180.0) % 360.0 - 180.0
        else:
            deg = float(np.degrees(np.arctan2(px, focal_px)))
        pairs.append(EdgePair(ea.key(), ea, eb, px, float(deg)))
    return pairs


def offset_summary(pairs: list[EdgePair]) -> dict:
    """{median, p95, count} of the absolute offsets in pixels (nan when none)."""
    values = np.abs([p.offset_px for p in pairs])
    if not len(values):
        return {"median": float("nan"), "p95": float("nan"), "count": 0}
    return {"median": float(np.median(values)), "p95": float(np.percentile(values, 95)), "count": int(len(values))}


# ---------------------------------------------------------------- hue crossings


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
    """The scale from the camera's channel weights S_c E normalised per channel (reports.prediction.
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


def _band_hue_crossings(signal: np.ndarray, band: _Band, total: np.ndarray, scale: HueScale, clip_row: np.ndarray | None,
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
    noise = _profile_noise(np.where(usable, nm, np.nan), band, max(2 * int(np.ceil(HOLD_PX / max(mean_step, 1e-6))), 1)) \
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
    periodic, pred, _, values, clip, steps = _sampled_profiles(polar, pred_samples, image, clipped)
    edges: list[Edge] = []
    n = pred.shape[-1]
    for p in range(polar.profile_count):
        roll = _seam(pred[:, :, p].sum(axis=(0, 1))) if periodic else 0
        lit = np.roll(np.nan_to_num(pred[:, :, p]), -roll, axis=-1)  # (orders, 3, n)
        step = np.roll(steps[p], -roll)
        total = lit.sum(axis=1)  # (orders, n)
        lit_any = (total > np.maximum(LIT_THRESHOLD * total.max(axis=1, keepdims=True), OTHER_ORDER_LIT)).any(axis=0)
        rgb = None if image is None else np.roll(values[:, p], -roll, axis=-1)
        clip_row = np.roll(clip[p], -roll) if clip is not None else None
        for i in range(len(orders)):
            if not total[i].max() > 0:
                continue
            for number, (first, last) in enumerate(_runs(total[i] > LIT_THRESHOLD * total[i].max())):
                if total[i, first:last + 1].max() < 3 * MIN_BAND_LIT:
                    continue
                band = _Band(i, 0, int(first), int(last), number)
                signal = lit[i] * scale.white[:, None] if rgb is None else _above_background(rgb, lit_any)
                for level, position, sigma_px, sat, snr, quality in _band_hue_crossings(
                        signal, band, total, scale, clip_row, step, correlation_px, levels, rgb is not None):
                    original = (position + roll) % n if periodic else position
                    xy = polar.point(p, original)
                    edges.append(Edge(polar.kind, p, polar.profile_label(p), orders[i], "hue", number, f"{level} nm",
                                      float(original), polar.coordinate(original), float(xy[0]), float(xy[1]),
                                      sigma_px, sat, snr, quality))
    return edges


# ---------------------------------------------------------------- the rim


@dataclass
class Rim:
    """The CD's rim ellipse in an image (cv2.fitEllipse's centre, full axes, angle in degrees)."""

    center: tuple[float, float]
    axes: tuple[float, float]
    angle_deg: float
    points: int
    rms_px: float

    def to_json(self) -> dict:
        return asdict(self)

    def affine_to(self, other: "Rim") -> np.ndarray:
        """The 2 x 3 affine map taking this ellipse onto ``other`` (centre, axes and orientation)."""
        return _ellipse_matrix(other) @ np.linalg.inv(_ellipse_matrix(self))[:, :]


def _ellipse_matrix(rim: Rim) -> np.ndarray:
    """Unit circle to the ellipse, as a 3 x 3 homogeneous matrix."""
    a, b = rim.axes[0] / 2, rim.axes[1] / 2
    t = np.radians(rim.angle_deg)
    rotation = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    m = np.eye(3)
    m[:2, :2] = rotation @ np.diag([a, b])
    m[:2, 2] = rim.center
    return m


def _grey(image: np.ndarray) -> np.ndarray:
    return np.asarray(image, np.float32)[..., :3].mean(axis=2)


def rim_points(image: np.ndarray, expected: np.ndarray, search_px: float = RIM_SEARCH_PX) -> np.ndarray:
    """Sub-pixel rim points: along the normal of the expected rim curve (pixels (N, 2), closed),
    the strongest brightness gradient within ``search_px`` (parabolic peak)."""
    grey = _grey(image)
    centre = expected.mean(axis=0)
    tangent = np.roll(expected, -1, axis=0) - np.roll(expected, 1, axis=0)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    normal *= np.sign(np.einsum("ij,ij->i", normal, expected - centre))[:, None]  # outward
    steps = np.arange(-search_px, search_px + 1e-9, 0.25)
    points = expected[:, None, :] + steps[None, :, None] * normal[:, None, :]
    values = cv2.remap(grey, points[..., 0].astype(np.float32), points[..., 1].astype(np.float32), cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    gradient = np.abs(np.gradient(values.astype(float), axis=1))
    found = []
    for i in range(len(expected)):
        g = gradient[i]
        if not np.all(np.isfinite(g)) or g.max() <= 0:
            continue
        k = int(np.argmax(g))
        if 0 < k < len(g) - 1:
            denom = g[k - 1] - 2 * g[k] + g[k + 1]
            k_sub = k + (0.5 * (g[k - 1] - g[k + 1]) / denom if denom != 0 else 0.0)
        else:
            continue  # the strongest edge is at the search's end: not the rim
        found.append(expected[i] + np.interp(k_sub, np.arange(len(steps)), steps) * normal[i])
    return np.asarray(found).reshape(-1, 2)


def _ellipse_residual(points: np.ndarray, rim: Rim) -> np.ndarray:
    """Approximate distance (px) of points from the ellipse."""
    inverse = np.linalg.inv(_ellipse_matrix(rim))
    unit = points @ inverse[:2, :2].T + inverse[:2, 2]
    r = np.linalg.norm(unit, axis=1)
    return (r - 1.0) * np.sqrt(rim.axes[0] * rim.axes[1]) / 2


def fit_rim(image: np.ndarray, expected: np.ndarray, search_px: float = RIM_SEARCH_PX) -> Rim | None:
    """The rim ellipse of the CD in ``image`` near the ``expected`` rim (pixels (N, 2)), or None."""
    points = rim_points(image, expected, search_px)
    keep = np.ones(len(points), bool)
    rim = None
    for _ in range(3):
        if keep.sum() < RIM_MIN_POINTS:
            return None
        (cx, cy), (w, h), angle = cv2.fitEllipse(points[keep].astype(np.float32))
        rim = Rim((float(cx), float(cy)), (float(w), float(h)), float(angle), int(keep.sum()), 0.0)
        residual = np.abs(_ellipse_residual(points, rim))
        keep = residual <= max(RIM_OUTLIER_PX, 3 * MAD_TO_SIGMA * float(np.median(residual[keep])))
    assert rim is not None
    rim.rms_px = float(np.sqrt(np.mean(_ellipse_residual(points[keep], rim) ** 2)))
    rim.points = int(keep.sum())
    return rim

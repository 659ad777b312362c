"""The CD's colour fringes measured in an image: its rim, and the edges of each order's lit band.

What a pixel sees (issue 15): the ceiling light spans about +-7 deg from the CD, so a
pixel of a diffracted band receives some 300 nm of spectrum and colour changes only
about 0.5 nm per pixel along a radius. The sharp, comparable features are the edges of
each order's lit band: where a colour channel's brightness crosses half its band maximum
(above the local background), along circles about the CD's centre and along radii.

How (per image: photo, render, or the prediction of renderer.trace.prediction):

* Profiles: the image is sampled on the polar grids of reports.fringes.polar (the same pixel
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
  own saturation, reports.compare.images.through_photo_sensor), else ``ok``.

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

The same profiles and predicted bands serve the hue crossings (reports.fringes.hue), and the CD's
rim is found in the same images (reports.fringes.rim).
"""


from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from reports.fringes.polar import PolarGrid, sample

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
class Band:
    """One predicted band along a profile: an order's run of lit samples in one channel."""

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


def true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) of each run of True."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(padded)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1, strict=True))


def _bands(pred: np.ndarray) -> list[Band]:
    """The predicted bands of one profile: pred (orders, 3, n) lit fractions (unrolled)."""
    out = []
    for i in range(pred.shape[0]):
        for c in range(3):
            line = pred[i, c]
            top = np.nanmax(line) if np.any(np.isfinite(line)) else 0.0
            if not top > 0:
                continue
            number = 0
            for first, last in true_runs(np.nan_to_num(line) > LIT_THRESHOLD * top):
                if np.nanmax(line[first:last + 1]) >= MIN_BAND_LIT:
                    out.append(Band(i, c, int(first), int(last), number))
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


def _band_top(line: np.ndarray, band: Band, smooth_samples: float) -> float:
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


def profile_noise(raw: np.ndarray, band: Band, lag: int) -> float:
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


EdgeFound = tuple[Band, str, float, float, float, float, str]  # (band, side, position, sigma_px, contrast, snr, quality)


@dataclass(frozen=True)
class _Steps:
    """A profile's sampling, for its edges: px per sample (each and mean), ``hold`` in samples,
    and the distance over which the image's noise is shared."""

    step_px: np.ndarray
    mean_step: float
    hold: int
    correlation_px: float


@dataclass(frozen=True)
class _BandLevels:
    """One band as its edges are measured: the profile the edges are found on, the window
    (w0, w1), the peak's sample, background, contrast, half level, noise sigma, and whether
    another order's band reaches into the window or saturated photo pixels lie in the band."""

    line: np.ndarray
    window: tuple[int, int]
    peak: int
    background: float
    contrast: float
    level: float
    sigma: float
    overlapping: bool
    is_clipped: bool


def _band_levels(line: np.ndarray, band: Band, window: tuple[int, int], lit: np.ndarray, lit_anywhere: np.ndarray,
                 raw: np.ndarray | None, clipped: np.ndarray | None, steps: _Steps,
                 own_prediction: bool) -> _BandLevels:
    """Background, maximum and half level of one band, its noise and its quality flags (module docstring)."""
    w0, w1 = window
    values = line[w0:w1 + 1]
    inside = line[band.start:band.stop + 1]
    peak = band.start + int(np.nanargmax(inside))
    # the band's maximum as a high percentile (the same for images and prediction): one bright
    # outlier must not raise the half level
    top = _band_top(line, band, TOP_SMOOTH_PX / max(steps.mean_step, 1e-6))
    if own_prediction:
        background = 0.0
    else:
        dark = ~lit_anywhere[w0:w1 + 1] & np.isfinite(values)
        background = float(np.median(values[dark])) if dark.any() else float(np.nanmin(values))
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
        where = Band(band.order_index, band.channel, w0, w1, band.number)
    sigma = 0.0 if noisy is None else profile_noise(noisy, where, max(2 * steps.hold, 1))
    return _BandLevels(line, window, peak, background, contrast, level, sigma, overlapping, is_clipped)


def _side_edge(b: _BandLevels, band: Band, side: str, direction: int, limit: int, steps: _Steps,
               own_prediction: bool) -> EdgeFound:
    """The band's edge on one side: the first crossing of the half level from the peak outward
    (by ``direction``, within ``limit``), refined by the ramp fit, with its uncertainty and quality."""
    line = b.line
    n = len(line)
    position = _crossing(line, b.peak, b.level, direction, limit, steps.hold) if b.contrast > 0 else None
    if position is None:
        return (band, side, float("nan"), float("nan"), b.contrast, float("nan"), "missing")
    j = int(np.clip(round(position), 1, n - 2))
    px = float(steps.step_px[j]) if np.isfinite(steps.step_px[j]) else steps.mean_step
    fitted = _ramp_fit(line, position, b.background, b.contrast, b.level, direction, px)
    if fitted is not None:
        position, slope, samples = fitted
    else:
        slope, samples = abs(line[min(j + 1, n - 1)] - line[max(j - 1, 0)]) / 2.0, 1  # per sample
    independent = max(1.0, samples * px / steps.correlation_px)
    sigma_px = b.sigma / slope * px / np.sqrt(independent) if slope > 0 else float("inf")
    snr = b.contrast / b.sigma if b.sigma > 0 else float("inf")
    faint = not own_prediction and b.contrast < MIN_RELATIVE_CONTRAST * abs(b.background)
    quality = ("overlap" if b.overlapping else
               "weak" if (snr < SNR_MIN or sigma_px > EDGE_SIGMA_MAX_PX or faint) else "clipped" if b.is_clipped else "ok")
    return (band, side, float(position), sigma_px, b.contrast, snr, quality)


def _profile_edges(values: np.ndarray | None, raw: np.ndarray | None, clipped: np.ndarray | None, pred: np.ndarray,
                   step_px: np.ndarray, own_prediction: bool, correlation_px: float = NOISE_CORRELATION_PX,
                   ) -> list[EdgeFound]:
    """Edges of every predicted band in one profile (unrolled): (band, side, position,
    sigma_px, contrast, snr, quality). ``values`` (3, n) is the image's smoothed profile and
    ``raw`` the same before smoothing; for the prediction itself (``own_prediction``) the
    per-order lit fractions ``pred`` are used instead."""
    n = pred.shape[-1]
    lit = np.nan_to_num(pred)
    lit_anywhere = (lit.max(axis=1) > np.maximum(LIT_THRESHOLD * lit.max(axis=(1, 2))[:, None], OTHER_ORDER_LIT)).any(axis=0)
    mean_step = float(np.nanmean(step_px)) if np.any(np.isfinite(step_px)) else 1.0
    extension = int(np.ceil(WINDOW_EXTENSION_PX / max(mean_step, 1e-6)))
    steps = _Steps(step_px, mean_step, int(np.ceil(HOLD_PX / max(mean_step, 1e-6))), correlation_px)
    found = []
    for band in _bands(pred):
        line = pred[band.order_index, band.channel] if own_prediction or values is None else values[band.channel]
        w0, w1 = max(band.start - extension, 0), min(band.stop + extension, n - 1)
        if not np.any(np.isfinite(line[w0:w1 + 1])):
            continue
        levels = _band_levels(line, band, (w0, w1), lit, lit_anywhere, raw, clipped, steps, own_prediction)
        for side, direction, limit in (("start", -1, w0), ("end", 1, w1)):
            if (side == "start" and band.start == 0) or (side == "end" and band.stop == n - 1):
                continue  # the band runs past the profile's end (into the rim or the hole): no edge there
            found.append(_side_edge(levels, band, side, direction, limit, steps, own_prediction))
    return found


def seam(total: np.ndarray) -> int:
    """Where a circle is cut open: a sample where the predicted bands are dimmest."""
    return int(np.argmin(np.nan_to_num(total, nan=np.inf)))


def sampled_profiles(polar: PolarGrid, pred_samples: np.ndarray, image: np.ndarray | None, clipped: np.ndarray | None):
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
               clipped: np.ndarray | None = None, correlation_px: float = NOISE_CORRELATION_PX,
               profiles: Iterable[int] | None = None) -> list[Edge]:
    """Band edges along every profile of ``polar``.

    ``pred_samples`` (orders, 3, radii, azimuths): the prediction sampled on the grid as the
    images are (reports.fringes.polar.sample with ``robust=True``), so that its own edges are comparable.
    ``image`` (H, W, 3) linear camera RGB; None measures the prediction's own edges.
    ``clipped`` (H, W) bool: saturated pixels. ``correlation_px``: the distance over which the
    image's noise is shared (``MOSAIC_CORRELATION_PX`` for a demosaiced raw photo).
    ``profiles``: only these profiles (all by default).
    """
    periodic, pred, raw, values, clip, steps = sampled_profiles(polar, pred_samples, image, clipped)
    edges: list[Edge] = []
    for p in (range(polar.profile_count) if profiles is None else sorted(set(profiles))):
        roll = seam(pred[:, :, p].sum(axis=(0, 1))) if periodic else 0
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


def signed_offset(polar: PolarGrid, a: Edge, b: Edge) -> float:
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
        px = signed_offset(polar, ea, eb)
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

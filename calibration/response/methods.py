"""The response-curve methods of calibration.response.calibrate, and the comparison of curves.

Methods, one short function each, in ``RESPONSE_METHODS`` (dispatcher: ``fit_response``);
each returns the inverse response as log normalised irradiance at the 256 values
y = k / 255, per channel:

* ``debevec``: OpenCV's ``CalibrateDebevec`` ([Debevec 1997, Eq. 3]: least squares
  on g = ln f^-1 with a smoothness term and a hat weight);
* ``robertson``: OpenCV's ``CalibrateRobertson`` ([Robertson 2003, Eqs. 8-9]: alternating ML
  estimates of irradiance and of the inverse response). It leaves values that never occur
  in the bracket as NaN; both OpenCV methods are masked there (Debevec's values are only
  extrapolated by its smoothness term);
* ``parametric`` (what the workbench uses): the inverse response g through its log-log
  slope s(y) = d ln g / d ln y, positive and piecewise linear in y on a few knots spread
  over the values the bracket shows, constant beyond them, integrated from g(1) = 1
  (``SlopeResponse``). Any positive slopes give a monotone curve; a pure gamma curve is one
  constant slope; below the data it is a power law (g(0) = 0). ln g is linear in the
  slopes, so the cost — the weighted spread of ln g(y_ij) - ln t_j over the exposures j
  of each pixel i, with ln E_i eliminated as its weighted mean ([Debevec 1997, Eq. 3]'s data
  term) — is quadratic, minimised with nlopt (L-BFGS, [Liu 1989]) within bounds on the slopes. Weights y^2 make the terms'
  variances about equal for a constant noise in y (d ln g / dy ~ s / y).

What makes the fit accurate on camera JPEGs (measured on the draft synthetic datasets,
where earlier versions of this fit missed the hidden curve by 2-8 %):
* the knots span only the values the bracket shows, the slope held constant beyond them:
  f(1) = 1 sets the irradiance scale, and a free knot above the brightest usable value let
  the fit slide the whole curve along a direction the data cannot see;
* whether a value is usable, and its weight, come from its neighbourhood's mean (5 x 5),
  not from the value itself: values kept because their own noise took them below the
  saturation threshold bias the top of the curve;
* pixels at edges (local spread over SMOOTH_WINDOW_PX, a JPEG block, above EDGE_FACTOR
  times the median) are left out, and Tukey-biweight reweighting drops the values no other
  exposure of their pixel agrees with (JPEG ringing, demosaicked neighbours of clipped
  raw pixels, anything that moved).

Curves are compared in the log domain over the mid-range (values 0.05-0.95), after
removing the unknown scale (a constant in ln E) of the OpenCV curves. A raw bracket's
linearity is the slope of ln(raw value) against ln(exposure time) (``linearity_slope``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import cv2
import nlopt
import numpy as np
from scipy.interpolate import PchipInterpolator

from calibration.response.bracket import SATURATED, Bracket, RawBracket
from workbench.core.errors import UserInputError

CURVE_VALUES = np.linspace(0.0, 1.0, 256)   # where every method reports its inverse response
MID_RANGE = (0.05, 0.95)                     # the values over which curves are compared
# Which pixels are sampled: at most SAMPLES_PER_BIN in each of SAMPLE_BINS irradiance bins,
# away from edges (local spread over SMOOTH_WINDOW_PX, a JPEG block, within EDGE_FACTOR
# times the image's median spread).
SAMPLE_BINS, SAMPLES_PER_BIN = 64, 60
SMOOTH_WINDOW_PX = 9
EDGE_FACTOR = 3.0
# The parametric fit.
DEFAULT_KNOTS = 6
SLOPE_BOUNDS = (0.05, 30.0)  # d ln g / d ln y: from a strong toe to a hard shoulder
TAPER_FROM = 0.9             # weights fall to 0 between this value and SATURATED
ROBUST_ITERATIONS = 3
TUKEY_C = 4.685
# A bracket is linear when |slope - 1| < LINEARITY_TOLERANCE.
LINEARITY_TOLERANCE = 0.02


@dataclass(frozen=True)
class InverseCurves:
    """An inverse response per channel: ln of normalised irradiance at ``CURVE_VALUES``
    (shape (256, len(channels))), NaN where the method knows nothing."""

    method: str
    channels: tuple[str, ...]
    log_irradiance: np.ndarray
    details: dict = field(default_factory=dict)

    def channel(self, name: str) -> np.ndarray:
        return self.log_irradiance[:, self.channels.index(name)]



# ---------------------------------------------------------------------------------------
# Methods
# ---------------------------------------------------------------------------------------

def _codes8(bracket: Bracket) -> tuple[list[np.ndarray], np.ndarray]:
    """The bracket as OpenCV's calibrators take it: 8-bit, 3 channels (16-bit images lose
    their low byte; grey is repeated), and which 8-bit codes occur (256, c)."""
    codes = bracket.codes if bracket.bits == 8 else (bracket.codes >> 8).astype(np.uint8)
    occurs = np.stack([np.bincount(codes[..., k].ravel(), minlength=256) > 0 for k in range(codes.shape[-1])], 1)
    if codes.shape[-1] == 1:
        codes = np.repeat(codes, 3, axis=-1)
    return [np.ascontiguousarray(image) for image in codes], occurs


def _opencv_curves(method: str, calibrator, bracket: Bracket) -> InverseCurves:
    images, occurs = _codes8(bracket)
    response = calibrator.process(images, bracket.times_s.astype(np.float32)).reshape(256, 3).astype(float)
    response = response[:, : len(bracket.channels)]
    with np.errstate(divide="ignore", invalid="ignore"):
        log_e = np.where(occurs & (response > 0), np.log(response), np.nan)
    return InverseCurves(method, bracket.channels, log_e, {"masked_values": int((~occurs).sum())})


def response_debevec(bracket: Bracket, samples: int = 70, smoothness: float = 10.0) -> InverseCurves:
    """[Debevec 1997, Eq. 3] through OpenCV's CalibrateDebevec: ``samples`` pixels on
    a grid (OpenCV's defaults), ``smoothness`` is their lambda. Values that never occur are masked."""
    return _opencv_curves("debevec", cv2.createCalibrateDebevec(samples, smoothness, False), bracket)


def response_robertson(bracket: Bracket, max_iter: int = 30, threshold: float = 0.01) -> InverseCurves:
    """[Robertson 2003, Eqs. 8-9] through OpenCV's CalibrateRobertson; it returns NaN
    for values that never occur, which are masked."""
    return _opencv_curves("robertson", cv2.createCalibrateRobertson(max_iter, threshold), bracket)


@dataclass(frozen=True)
class SlopeResponse:
    """An inverse response g given by its log-log slope s(y) = d ln g / d ln y > 0,
    piecewise linear in y through (``knots``, ``slopes``) and constant beyond the end
    knots, integrated from the normalisation g(1) = 1:

        ln g(y) = - integral from y to 1 of s(v) / v dv,

    so g is monotone for any positive slopes, a power law below the first knot (g(0) = 0),
    and a pure gamma curve is one constant slope. ln g is linear in the slopes."""

    knots: np.ndarray
    slopes: np.ndarray

    def log_irradiance(self, y: np.ndarray) -> np.ndarray:
        return -integrated_hats(np.asarray(y, dtype=float), self.knots) @ self.slopes


def integrated_hats(y: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """B_k(y) = integral from y to 1 of phi_k(v) / v dv for the hat functions phi_k on
    ``knots`` (extended as constants beyond the ends), (len(y), K), in closed form:
    on a knot interval [a, b] of width h, (b - v) / (h v) integrates to (b ln(q/p) - (q - p)) / h
    and (v - a) / (h v) to ((q - p) - a ln(q/p)) / h over [p, q]."""
    y = np.clip(np.ravel(y), 1e-300, 1.0)
    out = np.zeros((len(y), len(knots)))

    def overlap(lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
        p, q = np.maximum(y, lo), np.full_like(y, min(hi, 1.0))
        return p, np.maximum(q, p)

    p, q = overlap(0.0, knots[0])
    out[:, 0] += np.log(q / p)
    for m, (a, b) in enumerate(zip(knots[:-1], knots[1:], strict=True)):
        p, q = overlap(a, b)
        h, log_ratio = b - a, np.log(q / p)
        out[:, m] += (b * log_ratio - (q - p)) / h
        out[:, m + 1] += ((q - p) - a * log_ratio) / h
    p, q = overlap(knots[-1], 1.0)
    out[:, -1] += np.log(q / p)
    return out


@dataclass(frozen=True)
class PixelSamples:
    """Values of N pixels over the bracket's n exposures, (N, n), with weights (0 where
    unusable), and ln of the exposure times (n,)."""

    values: np.ndarray
    weights: np.ndarray
    log_times: np.ndarray


def _weight(level: np.ndarray) -> np.ndarray:
    """y^2 (equal variance of ln g(y) for a constant noise in y), tapered to 0 at SATURATED;
    of the local mean value, so that a pixel's own noise does not choose its weight."""
    taper = np.clip((SATURATED - level) / (SATURATED - TAPER_FROM), 0.0, 1.0)
    return level**2 * taper


def select_samples(bracket: Bracket, channels: Sequence[int], seed: int = 0) -> PixelSamples:
    """Pixels spread evenly over the scene's irradiances: binned by the sum of their values
    over the bracket (monotone in irradiance), at most SAMPLES_PER_BIN per bin, and only
    where the image is locally smooth (JPEG and demosaicking mix neighbours)."""
    rng = np.random.default_rng(seed)
    n, top = len(bracket.times_s), float(2**bracket.bits - 1)
    smooth = _smooth_pixels(bracket.codes.sum(0, dtype=np.float32) / top).ravel()
    picked_values, picked_weights = [], []
    for k in channels:
        level = bracket.levels[..., k].reshape(n, -1).T                  # (pixels, exposures)
        usable = bracket.usable[..., k].reshape(n, -1).T & smooth[:, None]
        informative = np.flatnonzero(usable.sum(1) >= 2)
        chosen = informative[_evenly_binned(level[informative].sum(1), rng)]
        picked_values.append(bracket.codes[..., k].reshape(n, -1).T[chosen] / top)
        picked_weights.append(np.where(usable[chosen], _weight(level[chosen]), 0.0))
    values, weights = np.concatenate(picked_values), np.concatenate(picked_weights)
    if len(values) == 0:
        raise UserInputError("no pixel keeps a usable value in two exposures", field="IMAGE",
                             expected="a bracket whose exposures overlap (values neither black nor saturated in two of them)",
                             got=list(bracket.files))
    return PixelSamples(values, weights, np.log(bracket.times_s))


def _evenly_binned(total: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices of at most SAMPLES_PER_BIN random entries in each of SAMPLE_BINS equal bins of ``total``."""
    if len(total) == 0:
        return np.zeros(0, dtype=int)
    bins = np.minimum((SAMPLE_BINS * (total - total.min()) / max(np.ptp(total), 1e-12)).astype(int), SAMPLE_BINS - 1)
    shuffled = rng.permutation(len(bins))
    by_bin = np.argsort(bins[shuffled].astype(np.uint8), kind="stable")    # a radix sort: by bin, randomly within one
    order, sorted_bins = shuffled[by_bin], bins[shuffled][by_bin]
    rank = np.arange(len(order)) - np.searchsorted(sorted_bins, np.arange(SAMPLE_BINS))[sorted_bins]
    return np.sort(order[rank < SAMPLES_PER_BIN])


def _smooth_pixels(image: np.ndarray) -> np.ndarray:
    """Pixels away from edges: the local spread of their values (over SMOOTH_WINDOW_PX, which
    covers a JPEG block: compression rings next to edges) at most EDGE_FACTOR times the
    image's median spread, so that smooth shading of any steepness stays."""
    grey = image.mean(-1).astype(np.float32)
    size = (SMOOTH_WINDOW_PX, SMOOTH_WINDOW_PX)
    mean = cv2.blur(grey, size)
    spread = np.sqrt(np.maximum(cv2.blur(grey * grey, size) - mean * mean, 0.0))
    return spread <= EDGE_FACTOR * np.median(spread)


def _knots(samples: PixelSamples, count: int) -> np.ndarray:
    """Knots evenly spaced in value over the values the samples show (from their 0.2 % to
    their 99.8 % quantile): the curve is measured there and extrapolated beyond as power laws."""
    y = samples.values[samples.weights > 0]
    lo, hi = np.quantile(y, [0.002, 0.998])
    return np.linspace(lo, hi, count)


def _normal_equations(samples: PixelSamples, weights: np.ndarray, knots: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The spread cost of ``fit_slope_response`` as s^T M s - 2 c^T s + d (it is quadratic
    in the slopes s, since ln g is linear in them and each ln E_i is a weighted mean)."""
    w = weights
    total = np.maximum(w.sum(1, keepdims=True), 1e-300)
    basis = integrated_hats(np.where(w > 0, samples.values, 1.0), knots).reshape(*w.shape, len(knots))
    centred_basis = basis - (w[..., None] * basis).sum(1, keepdims=True) / total[..., None]
    centred_times = samples.log_times - (w * samples.log_times).sum(1, keepdims=True) / total
    root = np.sqrt(w / w.sum())
    a = -(centred_basis * root[..., None]).reshape(-1, len(knots))   # residual = a s - b
    b = (centred_times * root).ravel()
    return a.T @ a, a.T @ b, float(b @ b)


def _residuals(model: SlopeResponse, samples: PixelSamples, weights: np.ndarray) -> np.ndarray:
    """Ln g(y_ij) - ln t_j - ln E_i, with ln E_i the weighted mean of each pixel."""
    z = model.log_irradiance(np.where(weights > 0, samples.values, 1.0)).reshape(weights.shape) - samples.log_times
    return z - (weights * z).sum(1, keepdims=True) / np.maximum(weights.sum(1, keepdims=True), 1e-300)


def _tukey_weights(residuals: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Tukey's biweight (1 - (e / c)^2)^2 of the standardised residuals e = r sqrt(w), with
    c = 4.685 robust standard deviations (1.4826 median |e|): 95 % efficient for Gaussian
    noise, and 0 for a value no exposure of its pixel agrees with ([Huber 1981];
    the constant from [Holland 1977])."""
    e = residuals * np.sqrt(weights)
    scale = 1.4826 * np.median(np.abs(e[weights > 0]))
    u = e / max(TUKEY_C * scale, 1e-300)
    return np.where(np.abs(u) < 1.0, (1.0 - u**2) ** 2, 0.0)


def _minimise_spread(samples: PixelSamples, weights: np.ndarray, knots: np.ndarray,
                     start: np.ndarray) -> tuple[np.ndarray, dict]:
    """The slopes minimising the quadratic spread cost, with nlopt's L-BFGS (exact gradient)."""
    m, c, d = _normal_equations(samples, weights, knots)

    def cost(slopes: np.ndarray, grad: np.ndarray) -> float:
        if grad.size:
            grad[:] = 2.0 * (m @ slopes - c)
        return float(slopes @ m @ slopes - 2.0 * c @ slopes + d)

    opt = nlopt.opt(nlopt.LD_LBFGS, len(knots))
    opt.set_min_objective(cost)
    opt.set_lower_bounds(np.full(len(knots), SLOPE_BOUNDS[0]))
    opt.set_upper_bounds(np.full(len(knots), SLOPE_BOUNDS[1]))
    opt.set_ftol_rel(1e-14)
    opt.set_xtol_rel(1e-10)
    opt.set_maxeval(10_000)
    slopes = opt.optimize(start)
    return slopes, {"cost": opt.last_optimum_value(), "nlopt_result": int(opt.last_optimize_result())}


def fit_slope_response(samples: PixelSamples, knots: int = DEFAULT_KNOTS) -> tuple[SlopeResponse, dict]:
    """The parametric inverse response: the knot slopes s minimising the weighted spread
    sum_ij w_ij (ln g(y_ij) - ln t_j - ln E_i)^2, each ln E_i at its weighted least-squares
    value ([Debevec 1997, Eq. 3]'s data term, without their smoothness term: a few
    knots are smooth enough), within SLOPE_BOUNDS from a gamma-2.2 start; then
    ROBUST_ITERATIONS reweightings with Tukey's biweight (iteratively reweighted least
    squares), which drop the values no other exposure of their pixel agrees with (JPEG
    ringing, a demosaicked neighbour of a clipped pixel, anything moving)."""
    if isinstance(knots, bool) or not isinstance(knots, int) or knots < 2:
        raise UserInputError("the parametric curve needs at least two knots", field="knots",
                             expected="an integer >= 2", got=knots)
    positions = _knots(samples, knots)
    weights = samples.weights
    slopes = np.full(knots, 2.2)
    for iteration in range(ROBUST_ITERATIONS + 1):
        slopes, info = _minimise_spread(samples, weights, positions, slopes)
        if iteration < ROBUST_ITERATIONS:
            model = SlopeResponse(positions, slopes)
            weights = samples.weights * _tukey_weights(_residuals(model, samples, weights), samples.weights)
    kept = (weights > 0).sum() / max((samples.weights > 0).sum(), 1)
    return SlopeResponse(positions, slopes), {
        "knots": positions.tolist(), "slopes": slopes.tolist(), **info,
        "samples": int((samples.weights > 0).any(1).sum()), "values_kept_by_robust_weights": float(kept)}


def response_parametric(bracket: Bracket, knots: int = DEFAULT_KNOTS, seed: int = 0) -> InverseCurves:
    """The workbench's curve: a monotone slope model (``fit_slope_response``) per channel
    and, for colour, on all channels' pixels pooled (channel ``all``)."""
    groups = [[k] for k in range(len(bracket.channels))]
    names = list(bracket.channels)
    if len(groups) > 1:
        groups.append(list(range(len(bracket.channels))))
        names.append("all")
    columns, details = [], {}
    for name, group in zip(names, groups, strict=True):
        model, info = fit_slope_response(select_samples(bracket, group, seed), knots)
        columns.append(_on_curve_values(model))
        details[name] = info
    return InverseCurves("parametric", tuple(names), np.stack(columns, 1), details)


def _on_curve_values(model: SlopeResponse) -> np.ndarray:
    """The model's ln g at CURVE_VALUES (-inf at y = 0)."""
    inside = CURVE_VALUES > 0
    out = np.full(len(CURVE_VALUES), -np.inf)
    out[inside] = model.log_irradiance(CURVE_VALUES[inside])
    return out


RESPONSE_METHODS: dict[str, Callable[..., InverseCurves]] = {
    "debevec": response_debevec,
    "robertson": response_robertson,
    "parametric": response_parametric,
}


def fit_response(bracket: Bracket, method: str = "parametric", **settings) -> InverseCurves:
    """Dispatch to one of RESPONSE_METHODS by name."""
    check_method(method)
    return RESPONSE_METHODS[method](bracket, **settings)


def check_method(method: str) -> None:
    """A UserInputError unless ``method`` names one of RESPONSE_METHODS."""
    if method not in RESPONSE_METHODS:
        raise UserInputError("unknown response method", field="method",
                             expected=" or ".join(f'"{m}"' for m in RESPONSE_METHODS), got=method)


# ---------------------------------------------------------------------------------------
# Curves as points, and comparing them
# ---------------------------------------------------------------------------------------

def curve_points(log_irradiance: np.ndarray) -> list[list[float]]:
    """[normalised irradiance, normalised value] pairs (truth.json's form) of a finite
    increasing inverse curve at CURVE_VALUES, from [0, 0] to [1, 1]."""
    x = np.exp(log_irradiance)
    keep = np.isfinite(x) & (CURVE_VALUES > 0) & (CURVE_VALUES < 1)
    pairs = [[0.0, 0.0]] + [[float(a), float(b)] for a, b in zip(x[keep], CURVE_VALUES[keep], strict=True)] + [[1.0, 1.0]]
    return pairs


def log_domain_difference(log_a: np.ndarray, log_b: np.ndarray, mid_range: tuple[float, float] = MID_RANGE) -> dict:
    """Ln g_a - ln g_b over the values in ``mid_range`` where both are known: the constant
    (the scale of irradiance, unknown to the OpenCV methods) and the RMS and largest
    deviation left after removing it."""
    inside = (CURVE_VALUES >= mid_range[0]) & (CURVE_VALUES <= mid_range[1]) & np.isfinite(log_a) & np.isfinite(log_b)
    if inside.sum() < 2:
        return {"values_compared": int(inside.sum()), "offset": None, "rms": None, "max_abs": None}
    d = log_a[inside] - log_b[inside]
    offset = float(d.mean())
    return {"values_compared": int(inside.sum()), "offset": offset, "rms": float(np.sqrt(np.mean((d - offset) ** 2))),
            "max_abs": float(np.max(np.abs(d - offset)))}


def response_rms(points, reference_points, value_range: tuple[float, float] = MID_RANGE, samples: int = 181) -> float:
    """RMS difference of two response curves (lists of [normalised irradiance, normalised
    value], read as monotone cubics like renderer.response) in normalised value, at the
    irradiances where the reference's value runs evenly over ``value_range``."""
    fitted, reference = (_forward(np.asarray(p, dtype=float)) for p in (points, reference_points))
    grid = np.linspace(0.0, 1.0, 8193)
    y = np.linspace(*value_range, samples)
    x = np.interp(y, reference(grid), grid)
    return float(np.sqrt(np.mean((fitted(x) - y) ** 2)))


def _forward(points: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    return PchipInterpolator(points[:, 0], points[:, 1])


# ---------------------------------------------------------------------------------------
# Raw brackets: linearity
# ---------------------------------------------------------------------------------------

def linearity_slope(raw: RawBracket) -> dict:
    """Slope b of ln(raw value) = b ln t + ln E_i over a raw bracket (each pixel's ln E_i
    eliminated by centring on its mean; values whose neighbourhood lies within RAW_USABLE of
    the black-to-white range, pixels with such values in two exposures at least), and how
    far it is from 1; also each exposure's median residual (a non-linearity or a wrong
    exposure time shows there). A linear sensor gives b = 1 (the linearity of
    [EMVA 1288, Sec. 6.4], here per pixel across the bracket rather than
    on a flat field)."""
    v, w, times = raw.values, raw.usable, raw.times_s
    keep = w.sum(1) >= 2
    v, w = v[keep], w[keep]
    log_v = np.log(np.where(w > 0, np.maximum(v, 1e-12), 1.0))
    log_t = np.broadcast_to(np.log(times), v.shape)

    def centred(a: np.ndarray) -> np.ndarray:
        return a - (w * a).sum(1, keepdims=True) / w.sum(1, keepdims=True)

    cv, ct = centred(log_v), centred(log_t)
    slope = float((w * cv * ct).sum() / (w * ct * ct).sum())
    residual = np.where(w > 0, cv - slope * ct, np.nan)
    return {"slope": slope, "slope_deviation": slope - 1.0, "linear": bool(abs(slope - 1.0) < LINEARITY_TOLERANCE),
            "tolerance": LINEARITY_TOLERANCE, "pixels": int(len(v)), "times_s": times.tolist(),
            "median_residual_per_exposure": [float(np.nanmedian(r)) if np.isfinite(r).any() else None
                                             for r in residual.T]}


def parametric_knot_study(bracket: Bracket, reference_points, knot_counts: Sequence[int] = (2, 3, 4, 5, 6, 8, 10),
                          seed: int = 0) -> list[dict]:
    """Accuracy against time of the parametric fit (pooled channels) for each number of
    knots: RMS error in normalised value against ``reference_points`` over the mid-range
    (``response_rms``), and seconds (sample selection included). For ``workbench study
    calibrate``, which may read a synthetic dataset's truth."""
    rows = []
    for knots in knot_counts:
        tick = time.perf_counter()
        model, _ = fit_slope_response(select_samples(bracket, range(len(bracket.channels)), seed), knots)
        seconds = time.perf_counter() - tick
        rows.append({"knots": knots, "rms": response_rms(curve_points(_on_curve_values(model)), reference_points),
                     "seconds": seconds})
    return rows

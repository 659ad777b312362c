"""The photo's own noise: a signal-dependent sensor model fitted to the photo itself.

Model ([Foi 2008], A. Foi, M. Trimeche, V. Katkovnik, K. Egiazarian, "Practical
Poissonian-Gaussian noise modeling and fitting for single-image raw-data", IEEE Trans.
Image Processing 17(10), Eqs. 1-3; the photon-transfer model of [EMVA 1288, Sec. 2]): a
raw value of mean level y (normalised: 0 black, 1 white) has variance a y + b, a from the
shot noise (the gain), b from the read noise and quantisation.

Estimated from one photo, as Foi et al. do, from many local (level, variance) pairs over
its smooth parts. Here each pair is three sites of one colour in a row, two sites apart
on the Bayer mosaic (so demosaicing never mixes them): level the three's mean, noise the
second difference (x0 - 2 x1 + x2) / sqrt(6), whose variance is the sites' own where the
image is locally linear. The triples are binned by level; per bin the variance is the mean
square of the triples within CLIP_SIGMAS robust standard deviations (the normalised median
absolute deviation) of the median: edges and texture in a few triples do not move it, and,
unlike the MAD itself, it is not biased where the noise is a few digital numbers. Bins
where more than MAX_CUT_SHARE of the triples touch 0 are left out (the decoder cuts at
black, and the noise with it). a, b >= 0 by non-negative weighted least squares. A photo
that is not raw (a linear EXR, or a JPEG through the response) is treated alike on each
channel's pixels; demosaicing may correlate its pixels, which the model does not see.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

LEVEL_BINS = 24
MIN_TRIPLES_PER_BIN = 200
MAD_TO_SIGMA = 1.4826  # a normal variable's MAD times this is its standard deviation
MAX_CUT_SHARE = 0.01   # a level bin with more triples than this touching black (cut there) is left out
CLIP_SIGMAS = 5.0      # triples beyond this many robust sigmas (edges, texture) left out; a normal loses 6e-7 of them


@dataclass(frozen=True)
class NoiseModel:
    """var(x) = shot * x + read, x the normalised raw value (module docstring)."""

    shot: float
    read: float
    triples: int
    bins: int
    basis: str  # "raw sites" or "pixels"

    def variance(self, level: np.ndarray) -> np.ndarray:
        return self.shot * np.maximum(level, 0.0) + self.read

    def to_json(self) -> dict:
        return {"variance": "shot * level + read (level normalised: 0 black, 1 white)", "shot": self.shot,
                "read": self.read, "read_sigma": float(np.sqrt(self.read)), "triples": self.triples,
                "level_bins": self.bins, "from": f"the photo's own {self.basis}: second differences of same-colour "
                "neighbours two sites apart, binned by level, variance within 5 robust sigmas (Foi et al. 2008)"}


def second_differences(rgb: np.ndarray, usable: np.ndarray,
                       channel: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel, the level and the second difference / sqrt 6 of the row triple centred on it
    (x[j-2], x[j], x[j+2]: one colour on a Bayer mosaic), NaN where the triple is not all usable
    (unclipped), and whether a site of it reads 0 (the decoder cuts at black, so its noise is
    cut too). Raw: (H, W), each site's own channel; otherwise (H, W, 3)."""
    values = (np.take_along_axis(rgb, channel[..., None], axis=2) if channel is not None else rgb).astype(np.float64)
    ok = np.broadcast_to(usable[..., None], values.shape)
    level, diff = np.full(values.shape, np.nan), np.full(values.shape, np.nan)
    cut = np.zeros(values.shape, bool)
    x0, x1, x2 = values[:, :-4], values[:, 2:-2], values[:, 4:]
    both = ok[:, :-4] & ok[:, 2:-2] & ok[:, 4:]
    level[:, 2:-2] = np.where(both, (x0 + x1 + x2) / 3.0, np.nan)
    diff[:, 2:-2] = np.where(both, (x0 - 2.0 * x1 + x2) / np.sqrt(6.0), np.nan)
    cut[:, 2:-2] = (x0 <= 0) | (x1 <= 0) | (x2 <= 0)
    if channel is not None:
        return level[..., 0], diff[..., 0], cut[..., 0]
    return level, diff, cut


def _bin_variance(d: np.ndarray) -> float | None:
    """The variance of a bin's second differences within CLIP_SIGMAS robust sigmas of the median."""
    centre = np.median(d)
    spread = MAD_TO_SIGMA * np.median(np.abs(d - centre))
    if spread <= 0:
        return None
    d = d[np.abs(d - centre) < CLIP_SIGMAS * spread]
    return float(np.mean((d - centre) ** 2))


def fit_noise(rgb: np.ndarray, clipped: np.ndarray, channel: np.ndarray | None) -> NoiseModel | None:
    """The photo's noise model (module docstring), or None where too few smooth triples exist."""
    level, diff, cut = second_differences(rgb, ~clipped, channel)
    keep = np.isfinite(diff)
    level, diff, cut = level[keep], diff[keep], cut[keep]
    if len(level) < LEVEL_BINS * MIN_TRIPLES_PER_BIN:
        return None
    edges = np.quantile(level, np.linspace(0.0, 1.0, LEVEL_BINS + 1))
    which = np.clip(np.searchsorted(edges, level, side="right") - 1, 0, LEVEL_BINS - 1)
    rows, values, weights = [], [], []
    for b in range(LEVEL_BINS):
        here = which == b
        if here.sum() < MIN_TRIPLES_PER_BIN or cut[here].mean() > MAX_CUT_SHARE:
            continue
        var = _bin_variance(diff[here & ~cut])
        if var is None:
            continue
        rows.append([max(float(np.mean(level[here])), 0.0), 1.0])
        values.append(var)
        weights.append(1.0 / (max(var, 1e-30) * np.sqrt(2.0 / here.sum())))
    if len(rows) < 2:
        return None
    w = np.asarray(weights)
    (shot, read), _ = nnls(np.asarray(rows) * w[:, None], np.asarray(values) * w)
    return NoiseModel(float(shot), float(read), int(len(level)), len(rows),
                      "raw sites" if channel is not None else "pixels")

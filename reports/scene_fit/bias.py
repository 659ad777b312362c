"""The forward model's own error, measured once on a render of the scene file (the scene fit's bias correction).

The scene fit's forward model (reports.scene_fit.model) puts the band edges where the
grating equation and the RCWA efficiencies put them, and the CD's rim on the projected
circle of the grating's edge. A photo's edges are found by an edge finder on an image
(blur, noise, the top's bright ring beside the rim, light from everywhere else in the
box), so each kind of edge carries a systematic offset the model does not have. Measured
on six unperturbed draft datasets (seeds 0-5, the true scene, the calibrated camera): the
photos' rim points lay 0.06-0.40 px outside the grating's circle (median per photo) with a
pattern by sector of -0.4..+0.7 px, and each band's edges sat off the prediction by a common
0.05-0.3 px; the fit read both as a moved CD (seed 5: tilt 0.69 deg off the truth at 4.9 of
its std).

A render of the scene file through the same calibrated camera, measured by the same edge
finders, shows the same offsets: the photo's rim against the render's had a median of
-0.003..+0.08 px and a robust spread of 0.08-0.35 px, against the photo's 0.31-0.48 px
against the circle (seeds 0, 4, 5, both views). So the offsets are measured on that render,
at the scene file's values, and subtracted from the photo's residuals: a band edge's
residual less its band's median offset (prediction minus render, over the band's edges of
quality ok, one channel, else all channels), a rim point's residual less the render's rim
residual at that place on the rim (the median over ``RIM_BIAS_NEIGHBOURS`` render rim points
on each side, by angle about the CD's projected centre). The correction is the output space
mapping of a cheap model onto an accurate one [Bandler 2004] and is held fixed while the fit
moves the scene: the offsets change slowly with it (a render of the fitted scene, verify's
confirming re-render, measures them again).

The render must show the band edges more precisely than a photo's edge of quality ok
(``RENDER_EDGE_SIGMA_MAX_PX``, reports.fringes.band_edges.EDGE_SIGMA_MAX_PX), by the statistic the
targeted render samples to (renderer.render_target.edge_sigma: the 90th percentile of
sigma_I / |grad I| over the CD's edge pixels, from the variance between its passes): verify's
render (``--target report``) reaches 0.18-0.21 px on a draft photo; a 4-spp render (about
3.6 px) gave band offsets of 4-11 px and rim offsets to 2.3 px, worse than no correction.
Without a usable render (``workbench fit`` without ``--renders``, a render of one pass, or
one too noisy) no correction is made, as before, and scene_fit.json says why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderer.render_target import edge_sigma
from reports.compare.images import Photo
from reports.fringes import band_edges as fringes

RENDER_EDGE_SIGMA_MAX_PX = fringes.EDGE_SIGMA_MAX_PX  # a render noisier than this at the CD's edges is not used
RIM_BIAS_NEIGHBOURS = 2  # render rim points on each side whose median is the bias at a photo rim point (~20 deg)
MIN_BAND_EDGES = 3  # render edges of quality ok a band needs for its own median; else its channels merged


@dataclass
class ViewBias:
    """One view's measured offsets: per edge key (of reports.fringes.band_edges), and the rim's by angle."""

    edges: dict[tuple, float]  # prediction minus render, px, per band edge key
    rim_angles: np.ndarray  # (N,) radians about the CD's projected centre, sorted
    rim_offsets: np.ndarray  # (N,) the render's rim residual (outward, px) there, smoothed
    centre_px: np.ndarray  # (2,) the CD's projected centre

    def edge(self, key: tuple) -> float:
        return self.edges.get(key, 0.0)

    def rim(self, points: np.ndarray) -> np.ndarray:
        """The render's rim offset at each photo rim point (N, 2), by its angle; 0 without render rim points."""
        if not len(self.rim_angles) or not len(points):
            return np.zeros(len(points))
        angles = np.arctan2(points[:, 1] - self.centre_px[1], points[:, 0] - self.centre_px[0])
        gap = np.abs(np.angle(np.exp(1j * (angles[:, None] - self.rim_angles[None]))))
        return self.rim_offsets[np.argmin(gap, axis=1)]


def band_offsets(render_edges: list[fringes.Edge], predicted: list[fringes.Edge], grid) -> dict[tuple, float]:
    """Per edge key: the median of prediction minus render over its band's edges (module docstring)."""
    by_key = {e.key(): e for e in predicted}
    one_channel: dict[tuple, list[float]] = {}
    merged: dict[tuple, list[float]] = {}
    for e in render_edges:
        p = by_key.get(e.key())
        if e.quality != "ok" or p is None or not np.isfinite(p.position):
            continue
        offset = -fringes.signed_offset(grid, p, e)  # signed_offset(a, b) is b minus a along the profile
        kind, _, order, channel, band, side = e.key()
        one_channel.setdefault((kind, order, channel, band, side), []).append(offset)
        merged.setdefault((kind, order, band, side), []).append(offset)
    out = {}
    for p in predicted:
        kind, _, order, channel, band, side = p.key()
        own = one_channel.get((kind, order, channel, band, side), [])
        values = own if len(own) >= MIN_BAND_EDGES else merged.get((kind, order, band, side), [])
        if len(values) >= MIN_BAND_EDGES:
            out[p.key()] = float(np.median(values))
    return out


def rim_offsets(angles: np.ndarray, residuals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The render's rim residuals sorted by angle, each replaced by the median over itself and
    ``RIM_BIAS_NEIGHBOURS`` neighbours on each side (around the closed rim)."""
    order = np.argsort(angles)
    a, r = angles[order], residuals[order]
    n, k = len(r), RIM_BIAS_NEIGHBOURS
    if n <= 2 * k:
        return a, np.full(n, float(np.median(r)) if n else 0.0)
    window = np.stack([np.roll(r, s) for s in range(-k, k + 1)])
    return a, np.median(window, axis=0)


def render_photo(rgb: np.ndarray) -> Photo:
    """A render as the edge finders take a photo: linear, nothing clipped."""
    return Photo(np.asarray(rgb, np.float32), np.zeros(rgb.shape[:2], bool), "render", "linear")


def usable_render(rgb: np.ndarray, variance: np.ndarray | None, cd: np.ndarray) -> tuple[bool, dict]:
    """Whether a render's CD edges are precise enough to measure the offsets on (module
    docstring), with its edge sigma; ``cd`` the CD's pixels (H, W)."""
    if variance is None:
        return False, {"used": False, "why": "the render has no variance between passes (one pass): its noise is unknown"}
    sigma, pixels = edge_sigma(np.asarray(rgb[..., :3], np.float64), np.asarray(variance[..., :3], np.float64), cd)
    note = {"render_edge_sigma_px": sigma, "edge_pixels": pixels}
    if not np.isfinite(sigma) or sigma > RENDER_EDGE_SIGMA_MAX_PX:
        return False, note | {"used": False, "why": f"the render's band edges are too noisy (sigma {sigma:.2f} px, "
                                                     f"at most {RENDER_EDGE_SIGMA_MAX_PX} px)"}
    return True, note | {"used": True}

"""Vignetting: the lens's relative illumination, fitted from the scene's walls against renders.

Model [Goldman 2010, Eq. 2: an even polynomial in the radius about the optical centre;
Kang 2000 for the physics], per channel c::

    V_c(x) = 1 + a_c1 x + a_c2 x^2 + a_c3 x^3,   x = ((u - cx) / fx)^2 + ((v - cy) / fy)^2,

the squared tangent of the field angle of pixel (u, v) (distorted pixels: the polynomial
absorbs the radial distortion's share), so V = 1 on the axis and the coefficients belong
to the lens, not to the resolution. A photo is V times what the lens would record without
vignetting, which is what the renderer draws.

Fit. Each photo is compared with a render of the scene file seen by its fitted camera
(the pose's render check's last one, calibration.intrinsics.vignetting_stage): over the walls
(calibration.pose.render_check's photometric mask: the diffuse surfaces, away from edges,
the CD, the glass, the light and saturated pixels) the image is cut into TILE_PX tiles, and per tile and channel the ratio
t = sum(photo) / sum(render) of the masked pixels is one datum, with its variance from the
pixels' own scatter about t. Per channel, t_j(x) = s_j V(x) over the photos j, with a
scale s_j per photo (its exposure x light power x the channel's gain, which the walls'
spectra leave free), is fitted by weighted nonlinear least squares with a soft-L1 loss
(scipy.optimize.least_squares; a tile on a misplaced edge or a caustic is an outlier). The
coefficients' covariance is the Gauss-Newton one scaled by the residuals' robust
chi^2 / dof; the corners' V and its std follow by the delta method. Tiles come from every
photo, so photos taken from different places separate the lens's falloff (fixed in the
image) from a model error in the scene's lighting (fixed in the world); on a real photo
what is left of such an error is fitted as vignetting, which the corners' std does not
cover.

Whether to use it: ``applied`` when some channel's V at some image corner is below 1 by
more than DETECT_SIGMA of its std and by more than MIN_FALLOFF (5 %; real lenses lose
20-50 % there); otherwise the record says why not, and the exposure scales and the report
are left as without the stage. The 5 % is what the walls cannot tell from a camera whose
model is off at the corners: on a synthetic fisheye dataset without vignetting, whose
board views missed the image's corners, the fitted camera's render made the corners 2-3 %
brighter than the photo (at 6 std), and flat (0.7 %, 1.4 std) at the true camera.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from renderer.camera import CameraModel

TILE_PX = 16
MIN_TILE_SHARE = 0.5    # a tile counts when at least this share of its pixels are wall pixels
DEGREE = 3              # terms a_1 .. a_3 (Goldman's r^2, r^4, r^6)
DETECT_SIGMA = 3.0
MIN_FALLOFF = 0.05      # a corner darker by under 5 % is not applied (module docstring: a camera off at the corners does that)
CHANNELS = ("R", "G", "B")
MODEL = "1 + a1 x + a2 x^2 + a3 x^3 per channel, x = ((u - cx) / fx)^2 + ((v - cy) / fy)^2 [Goldman 2010]"


@dataclass(frozen=True)
class WallTiles:
    """One photo's data: per tile its x (mean over the tile's wall pixels), ratio and ratio variance, per channel."""

    x: np.ndarray           # (N,)
    ratio: np.ndarray       # (N, 3)
    variance: np.ndarray    # (N, 3)
    photo_sum: np.ndarray   # (N, 3) the photo's sum over the tile's wall pixels
    render_sum: np.ndarray  # (N, 3) the render's
    centre: np.ndarray      # (N, 2) the tile's centre (u, v), pixels


def squared_field_tangent(camera: CameraModel, shape: tuple[int, int] | None = None) -> np.ndarray:
    """The squared field tangent x of every pixel (H, W) for ``camera``'s fx, fy, cx, cy."""
    h, w = shape or (camera.height, camera.width)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    return _field_x(camera, u, v)


def _field_x(camera: CameraModel, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return ((u - camera.cx) / camera.fx) ** 2 + ((v - camera.cy) / camera.fy) ** 2


def wall_tiles(photo_rgb: np.ndarray, render_rgb: np.ndarray, mask: np.ndarray, camera: CameraModel) -> WallTiles:
    """The tiles of one photo (module docstring): photo and render in any units, mask of the walls."""
    h, w = mask.shape
    rows, cols = h // TILE_PX, w // TILE_PX
    cut = (slice(0, rows * TILE_PX), slice(0, cols * TILE_PX))

    def tiled(a: np.ndarray) -> np.ndarray:  # (rows, cols, TILE_PX^2, ...)
        a = a[cut]
        return a.reshape(rows, TILE_PX, cols, TILE_PX, *a.shape[2:]).swapaxes(1, 2).reshape(rows * cols, TILE_PX**2,
                                                                                              *a.shape[2:])

    m = tiled(mask.astype(np.float64))
    p, r = tiled(np.asarray(photo_rgb, np.float64)) * m[..., None], tiled(np.asarray(render_rgb, np.float64)) * m[..., None]
    x_sum = (tiled(squared_field_tangent(camera, mask.shape)) * m).sum(axis=1)
    n = m.sum(axis=1)
    keep = (n >= MIN_TILE_SHARE * TILE_PX**2) & np.all(r.sum(axis=1) > 0, axis=1)
    p, r, n, x = p[keep], r[keep], n[keep], x_sum[keep] / n[keep]
    photo_sum, render_sum = p.sum(axis=1), r.sum(axis=1)
    ratio = photo_sum / render_sum
    scatter = ((p - ratio[:, None, :] * r) ** 2).sum(axis=1) / np.maximum(n[:, None] - 1, 1)  # per pixel, about t r
    variance = scatter * n[:, None] / render_sum**2
    index = np.flatnonzero(keep)
    centre = np.stack([(index % cols + 0.5) * TILE_PX - 0.5, (index // cols + 0.5) * TILE_PX - 0.5], axis=1)
    return WallTiles(x, ratio, np.maximum(variance, 1e-12 * ratio**2), photo_sum, render_sum, centre)


def falloff(coefficients: np.ndarray, x: np.ndarray) -> np.ndarray:
    """V(x) = 1 + sum_k a_k x^k for one channel's coefficients (DEGREE,)."""
    return 1.0 + sum(a * np.asarray(x, float) ** (k + 1) for k, a in enumerate(coefficients))


def _fit_channel(tiles: list[WallTiles], c: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(coefficients, their covariance, the photos' scales, robust chi^2/dof) of channel ``c``."""
    x = [t.x for t in tiles]
    y = [t.ratio[:, c] for t in tiles]
    sigma = [np.sqrt(t.variance[:, c]) for t in tiles]

    def residuals(q: np.ndarray) -> np.ndarray:
        a, scales = q[:DEGREE], q[DEGREE:]
        return np.concatenate([(yj - s * falloff(a, xj)) / sj for xj, yj, sj, s in zip(x, y, sigma, scales, strict=True)])

    start = np.concatenate([np.zeros(DEGREE), [float(np.median(yj)) for yj in y]])
    fit = least_squares(residuals, start, loss="soft_l1", f_scale=3.0, x_scale="jac")
    dof = max(fit.fun.size - fit.x.size, 1)
    chi2 = float(2.0 * fit.cost / dof)  # the soft-L1 cost: what the inliers' squares are to a quadratic loss
    jac = fit.jac
    covariance = np.linalg.pinv(jac.T @ jac) * max(chi2, 1.0)
    return fit.x[:DEGREE], covariance[:DEGREE, :DEGREE], fit.x[DEGREE:], chi2


def corner_x(camera: CameraModel) -> np.ndarray:
    """The squared field tangent x at the image's four corner pixels (top-left, top-right, bottom-left, bottom-right)."""
    u = np.array([0.0, camera.width - 1.0, 0.0, camera.width - 1.0])
    v = np.array([0.0, 0.0, camera.height - 1.0, camera.height - 1.0])
    return _field_x(camera, u, v)


def fit_vignetting(tiles: dict[str, WallTiles], camera: CameraModel) -> dict:
    """calibration.json's ``vignetting`` from the photos' tiles (by photo name), the camera's intrinsics."""
    tick = time.perf_counter()
    names = list(tiles)
    corners = corner_x(camera)
    powers = np.stack([corners**(k + 1) for k in range(DEGREE)], axis=1)  # (4, DEGREE): dV/da at the corners
    out: dict = {"model": MODEL, "tile_px": TILE_PX, "tiles": {name: int(t.x.size) for name, t in tiles.items()},
                 "x_covered_max": float(max(t.x.max() for t in tiles.values())), "x_corners": corners.tolist(),
                 "coefficients": {}, "coefficients_std": {}, "corners": {}, "corners_std": {}, "scales": {}, "chi2_dof": {}}
    for c, channel in enumerate(CHANNELS):
        a, cov, scales, chi2 = _fit_channel([tiles[n] for n in names], c)
        out["coefficients"][channel] = a.tolist()
        out["coefficients_std"][channel] = np.sqrt(np.diag(cov)).tolist()
        out["corners"][channel] = falloff(a, corners).tolist()
        out["corners_std"][channel] = np.sqrt(np.einsum("ik,kl,il->i", powers, cov, powers)).tolist()
        out["scales"][channel] = dict(zip(names, scales.tolist(), strict=True))
        out["chi2_dof"][channel] = chi2
    out["applied"], out["why"] = _decision(out)
    out["seconds"] = time.perf_counter() - tick
    return out


def _decision(record: dict) -> tuple[bool, str]:
    """Applied when some channel's falloff at some corner is over DETECT_SIGMA std and MIN_FALLOFF; and why."""
    corners = [(1.0 - v, abs(1.0 - v) / max(s, 1e-300), ch)
               for ch in CHANNELS for v, s in zip(record["corners"][ch], record["corners_std"][ch], strict=True)]
    detected = [c for c in corners if c[1] > DETECT_SIGMA and c[0] > MIN_FALLOFF]
    fall, sigmas, channel = max(detected or corners, key=lambda c: abs(c[0]))
    what = f"the largest corner falloff {'that is detected ' if detected else ''}is {100 * fall:.1f} % ({channel}), " \
           f"{sigmas:.1f} of its std"
    if detected:
        return True, f"{what}: darker by {DETECT_SIGMA:g} std and {100 * MIN_FALLOFF:g} %, so the photos are compared through it"
    return False, f"{what}; no corner is darker by both {DETECT_SIGMA:g} std and {100 * MIN_FALLOFF:g} %, so it is not applied"


def relative_illumination(record: dict | None, camera: CameraModel) -> np.ndarray | None:
    """(H, W, 3) V of an applied ``vignetting`` record at ``camera``'s pixels, or None (none, or not applied)."""
    if not record or not record.get("applied"):
        return None
    x = squared_field_tangent(camera)
    return np.stack([falloff(np.asarray(record["coefficients"][ch], float), x) for ch in CHANNELS], axis=2)


def vignetting_summary(record: dict | None) -> dict:
    """What report.json says of the lens's falloff: applied or not, why, and the corners' V with std."""
    if record is None:
        return {"applied": False, "why": "the camera file records no vignetting (calibrate DATASET fits it)"}
    keys = ("applied", "why", "model", "coefficients", "corners", "corners_std")
    return {key: record[key] for key in keys if key in record}

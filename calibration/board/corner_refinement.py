"""Sub-pixel corners by point symmetry, all corners of a view fitted at once.

A checkerboard corner q is a centre of point symmetry: I(q + v) = I(q - v) for every v
in a disc around it, however the board is tilted, and so is its image after pixel
averaging, blur and any monotone response (locally the pattern is an affine image of the
board, which keeps the symmetry). The criterion is that of saddle-point / symmetry corner
detectors ([Chen 2005]; [Lucchese 2002]), written here as
a least-squares fit over the integer offsets k of a half disc (each pair k, -k once) with
a linear shading term h that takes up a light's fall-off across the disc:

    e(k) = I(q + k) - I(q - k) - (h . k) (I(q + k) + I(q - k)),   minimise sum e^2 over q, h.

Unlike cornerSubPix's gradient-orthogonality criterion it is not biased by perspective
(0.02-0.03 px on rasterized tilted boards against cornerSubPix's 0.04-0.07,
tests/calibration/test_corners.py).

The fit is Gauss-Newton with a little Levenberg-Marquardt damping ([Madsen 2004,
Sec. 3.2]), the 4 x 4 normal equations of every corner solved together (numpy's batched
solve). The image is interpolated with Keys' cubic convolution ([Keys 1981,
Eq. 15]) and its exact derivative, so the Jacobian is that of the interpolant itself
(cv2.remap quantises sub-pixel positions to 1/32 pixel, which would put steps into the
cost). Keys' parameter is a = -0.75 (OpenCV's and Photoshop's choice) rather than Keys'
-0.5: on the rasterized boards -0.5 gave 0.032-0.055 px, -0.75 0.024-0.029 px; the
sharper kernel follows the squares' edges better. Because the offsets are integers, all
of a corner's samples share q's fractional part and the same 16 interpolation weights.
"""

from __future__ import annotations

import numpy as np

RADIUS_FACTOR = 0.7        # disc radius over the distance to the nearest neighbouring corner
MIN_RADIUS_PX = 2.0
KEYS_A = -0.75             # Keys' kernel parameter (OpenCV's INTER_CUBIC uses it too)
MAX_RADIUS_PX = 40.0       # larger squares gain nothing from a larger disc, and cost its area
MAX_ITERATIONS = 30
STEP_TOLERANCE_PX = 3e-3   # stop when no corner moves more than this (steps shrink about 3x per iteration)
MAX_STEP_PX = 1.0          # a Gauss-Newton step longer than this is shortened to it
DAMPING = 1e-6             # Levenberg-Marquardt lambda, relative to the normal matrix's diagonal
MAX_SHIFT_FRACTION = 0.3   # a corner that moves further than this times its spacing is not trusted
MIN_VALID_FRACTION = 0.5   # pairs whose both samples lie inside the image, at least
FEW_CORNERS = 16           # below this many corners still iterating, their blocks are multiplied one by one


def _half_disc(radius: int) -> np.ndarray:
    """Integer offsets k (K, 2) = (x, y) within ``radius`` of the origin, each pair (k, -k) once."""
    ky, kx = np.mgrid[-radius:radius + 1, -radius:radius + 1]
    keep = (kx**2 + ky**2 <= radius**2) & ((ky > 0) | ((ky == 0) & (kx > 0)))
    return np.stack([kx[keep], ky[keep]], 1)


def _keys_weights(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keys' cubic convolution weights (a = KEYS_A) of the taps at -1, 0, 1, 2 for fractions ``t`` (M,), and
    their derivatives in t. Kernel ([Keys 1981, Eq. 15]): (a+2)|s|^3 - (a+3)|s|^2 + 1 for |s| <= 1,
    a|s|^3 - 5a|s|^2 + 8a|s| - 4a for 1 < |s| < 2."""
    a = KEYS_A
    t2, t3 = t * t, t * t * t
    u = 1.0 - t
    u2, u3 = u * u, u * u * u
    w = np.empty(t.shape + (4,), t.dtype)
    dw = np.empty_like(w)
    w[..., 0] = a * (t3 + 1 + 3 * t + 3 * t2) - 5 * a * (1 + 2 * t + t2) + 8 * a * (1 + t) - 4 * a  # s = 1 + t
    w[..., 1] = (a + 2) * t3 - (a + 3) * t2 + 1                                                      # s = t
    w[..., 2] = (a + 2) * u3 - (a + 3) * u2 + 1                                                      # s = 1 - t
    w[..., 3] = 1.0 - w[..., 0] - w[..., 1] - w[..., 2]                                              # s = 2 - t
    dw[..., 0] = 3 * a * (1 + t) ** 2 - 10 * a * (1 + t) + 8 * a
    dw[..., 1] = 3 * (a + 2) * t2 - 2 * (a + 3) * t
    dw[..., 2] = -(3 * (a + 2) * u2 - 2 * (a + 3) * u)
    dw[..., 3] = -(dw[..., 0] + dw[..., 1] + dw[..., 2])
    return w, dw


class DiscSampler:
    """The image, interpolated with Keys' cubic and differentiated, at q + k and q - k for every offset k of a
    lattice disc (|k| <= radius, integers) about each corner q.

    All of a corner's samples share q's fractional part, so each sample is the same 16
    weights applied to its own 4 x 4 neighbourhood. The neighbourhoods are cut once from a
    crop about q's pixel (again only for a corner that crosses into another pixel), and a
    Gauss-Newton step costs two batched (3 x 16) by (16 x K) products.
    """

    def __init__(self, grey: np.ndarray, offsets: np.ndarray, radius: int, corners: int) -> None:
        self.height, self.width = grey.shape
        self.radius = radius
        self.side = 2 * radius + 1
        self._pad = radius + 3
        self._padded = np.pad(np.asarray(grey, np.float32), self._pad, mode="edge")
        self._windows = np.lib.stride_tricks.sliding_window_view(self._padded, (self.side + 3, self.side + 3))
        self._steps = np.arange(self.side + 3) - radius - 1        # crop rows / columns relative to q's pixel
        kx, ky = offsets[:, 0], offsets[:, 1]
        self._plus = (radius + ky) * self.side + (radius + kx)      # flat lattice index of q + k
        self._minus = (radius - ky) * self.side + (radius - kx)     # and of q - k
        crop_side = self.side + 3
        taps = np.arange(4)
        tap_offset = (taps[:, None] * crop_side + taps[None, :]).reshape(16, 1)   # tap (t, u) in the flat crop
        self._crop_plus = tap_offset + (radius + ky) * crop_side + (radius + kx)   # (16, K)
        self._crop_minus = tap_offset + (radius - ky) * crop_side + (radius - kx)
        self._anchor = np.full((corners, 2), np.iinfo(np.int64).min)
        self._blocks = np.empty((2, corners, 16, len(offsets)), np.float32)   # (+k / -k, corner, tap, k)
        self._inside = np.zeros((corners, len(offsets)), bool)

    def _gather(self, which: np.ndarray, anchor: np.ndarray) -> None:
        x0 = np.clip(anchor[:, 0], -self.radius - 1, self.width + self.radius)
        y0 = np.clip(anchor[:, 1], -self.radius - 1, self.height + self.radius)
        s, n = self.side, len(which)
        first = self._pad - self.radius - 1                                     # the crop's first row/column, padded
        crop = self._windows[y0 + first, x0 + first]                            # (n, side + 3, side + 3), a copy
        flat = crop.reshape(n, -1)
        self._blocks[0, which] = np.take(flat, self._crop_plus, 1)
        self._blocks[1, which] = np.take(flat, self._crop_minus, 1)
        lattice_x = x0[:, None] + self._steps[None, 1:s + 1]
        lattice_y = y0[:, None] + self._steps[None, 1:s + 1]
        inside = (((lattice_y >= 0) & (lattice_y <= self.height - 1))[:, :, None]
                  & ((lattice_x >= 0) & (lattice_x <= self.width - 1))[:, None, :]).reshape(n, -1)
        self._inside[which] = np.take(inside, self._plus, 1) & np.take(inside, self._minus, 1)
        self._anchor[which] = anchor

    def sample(self, q: np.ndarray, which: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For the corners ``which`` at q (len(which), 2): (fields at q + k, fields at q - k, both inside the
        image); fields (n, 3, K) are value, d/dx, d/dy."""
        anchor = np.floor(q).astype(np.int64)
        moved = np.flatnonzero(np.any(anchor != self._anchor[which], axis=1))
        if len(moved):
            self._gather(which[moved], anchor[moved])
        fx, fy = (q - anchor).T
        wx, dwx = _keys_weights(fx)
        wy, dwy = _keys_weights(fy)
        weights = np.stack([wy[:, :, None] * wx[:, None, :], wy[:, :, None] * dwx[:, None, :],
                            dwy[:, :, None] * wx[:, None, :]], 1).reshape(len(q), 3, 16).astype(np.float32)
        if len(which) == self._blocks.shape[1]:
            return weights @ self._blocks[0], weights @ self._blocks[1], self._inside
        if len(which) <= FEW_CORNERS:   # no copy of the few corners' blocks: one small product each
            plus = np.stack([w @ self._blocks[0, j] for w, j in zip(weights, which, strict=True)])
            minus = np.stack([w @ self._blocks[1, j] for w, j in zip(weights, which, strict=True)])
            return plus, minus, self._inside[which]
        return weights @ self._blocks[0, which], weights @ self._blocks[1, which], self._inside[which]


def refine_by_symmetry(grey: np.ndarray, corners: np.ndarray, spacing: np.ndarray,
                       radius_factor: float = RADIUS_FACTOR) -> tuple[np.ndarray, np.ndarray]:
    """Corners (N, 2) moved to the centre of point symmetry of ``grey`` (float, H x W) around them.

    ``spacing`` (N,) is each corner's distance to its nearest neighbouring corner, pixels:
    the disc has radius ``radius_factor * spacing`` (at least 2 px, at most MAX_RADIUS_PX).
    Returns the refined corners and a mask of those the fit trusts: it converged, kept at
    least half of its sample pairs inside the image, and moved less than 0.3 times the
    spacing. The others are returned where they came in.
    """
    start = np.asarray(corners, float).reshape(-1, 2)
    spacing = np.asarray(spacing, float).reshape(-1)
    radius = np.clip(radius_factor * spacing, MIN_RADIUS_PX, MAX_RADIUS_PX)
    lattice_radius = int(np.ceil(radius.max()))
    k = _half_disc(lattice_radius)
    in_disc = np.linalg.norm(k, axis=1)[None, :] <= radius[:, None]            # (N, K)
    sampler = DiscSampler(grey, k, lattice_radius, len(start))
    q, h = start.copy(), np.zeros_like(start)    # h: the shading gradient per pixel
    converged = np.zeros(len(q), bool)
    valid = in_disc.copy()
    offsets = k.astype(float)
    for _ in range(MAX_ITERATIONS):
        active = np.flatnonzero(~converged)          # corners stop as they converge: the slowest set the count
        e, J, valid[active] = _residuals_and_jacobian(*sampler.sample(q[active], active), offsets, h[active],
                                                      in_disc[active])
        A = (J @ J.transpose(0, 2, 1)).astype(float)
        b = (J @ e[..., None])[..., 0].astype(float)
        A[:, np.arange(4), np.arange(4)] *= 1.0 + DAMPING
        A[:, np.arange(4), np.arange(4)] += 1e-12
        step = -np.linalg.solve(A, b[..., None])[..., 0]
        length = np.linalg.norm(step[:, :2], axis=1)
        step *= np.minimum(1.0, MAX_STEP_PX / np.maximum(length, 1e-300))[:, None]
        q[active] += step[:, :2]
        h[active] += step[:, 2:]
        converged[active] = length < STEP_TOLERANCE_PX
        if converged.all():
            break
    kept = valid.sum(axis=1) / np.maximum(in_disc.sum(axis=1), 1)
    trusted = (converged & (kept >= MIN_VALID_FRACTION)
               & (np.linalg.norm(q - start, axis=1) < MAX_SHIFT_FRACTION * spacing) & np.isfinite(q).all(axis=1))
    return np.where(trusted[:, None], q, start), trusted


def _residuals_and_jacobian(plus: np.ndarray, minus: np.ndarray, inside: np.ndarray, k: np.ndarray, h: np.ndarray,
                            in_disc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residuals e (N, K) and de/d(qx, qy, hx, hy) as (N, 4, K) from the fields (N, 3, K) at q + k and q - k, and the kept
    mask; pairs outside the disc or the image have zero Jacobian rows, so they drop out of J^T J and J^T e.
    float32: the sums over a disc's pairs need no more."""
    valid = in_disc & inside
    shading = (h @ k.T).astype(np.float32)                                     # (N, K)
    total = plus[:, 0] + minus[:, 0]
    e = plus[:, 0] - minus[:, 0] - shading * total
    J = np.empty((len(e), 4, e.shape[1]), np.float32)
    J[:, 0:2] = plus[:, 1:3] - minus[:, 1:3]
    J[:, 0:2] -= shading[:, None] * (plus[:, 1:3] + minus[:, 1:3])
    J[:, 2] = -k[:, 0].astype(np.float32) * total
    J[:, 3] = -k[:, 1].astype(np.float32) * total
    J *= valid[:, None]
    return e, J, valid

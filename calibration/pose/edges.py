"""Edges in a photograph, for aligning a scene's known 3D edges with it.

Two measurements, coarse and fine:

* ``ChamferMap``: a truncated Euclidean distance transform of the photo's Canny edges
  ([Canny 1986]), at a chosen scale: the cost of projected model
  points is the mean of their squared distances to the nearest photo edge, capped at
  ``tau`` so that model points whose edge is hidden or faint cost a constant
  (chamfer matching, [Barrow 1977]; truncated as in robust chamfer
  variants). It is smooth enough for a derivative-free optimiser and has a wide basin.
* ``edge_offsets``: the sub-pixel position of the edge along a projected edge's normal:
  the photo's linear intensity is sampled on a short 2D strip across the predicted
  edge (bilinear), averaged along it, differentiated, and the extremum of the
  derivative is located by a parabola through its three highest samples (the 1D
  search of the "moving edges" trackers: [Harris 1992]; [Drummond 2002]).
  Linear intensity matters: a pixel integrates light linearly, so a step blurred by a
  symmetric kernel has its steepest point on the true edge, which a gamma would move.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

CANNY_SIGMA_PX = 1.0
STRIP_HALF_WIDTH_PX = 1.5   # half-length of the strip along the edge that is averaged
STRIP_STEP_PX = 0.5         # sample spacing across and along the edge
PRESMOOTH_SIGMA_PX = 0.7    # a symmetric blur against pixel noise: it does not move a symmetric step's steepest point
LOBE_HALF_WIDTH_PX = 2.0  # the derivative's centroid is taken this far either side of its peak
LOBE_FLOOR = 0.1            # ... over the part above this share of the peak (drops noise and shading slopes)


def display_grey(linear: np.ndarray) -> np.ndarray:
    """Linear grey to 8 bits for Canny: its 99th percentile at full scale, then a 1/2.2 power
    so that dark creases and bright walls both show edges."""
    top = float(np.percentile(linear, 99.0))
    scaled = np.clip(linear / max(top, 1e-12), 0.0, 1.0) ** (1 / 2.2)
    return np.rint(scaled * 255).astype(np.uint8)


def canny_edges(linear: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Canny edges (uint8, 255 on edges) of the linear grey image resampled by ``scale``,
    with thresholds from the median gradient (a fixed share of the image is edge)."""
    grey = display_grey(linear)
    if scale != 1.0:
        grey = cv2.resize(grey, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    grey = cv2.GaussianBlur(grey, (0, 0), CANNY_SIGMA_PX)
    gx = cv2.Sobel(grey, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(grey, cv2.CV_32F, 0, 1)
    magnitude = np.hypot(gx, gy)
    high = float(np.percentile(magnitude, 90.0))
    return cv2.Canny(grey, max(0.4 * high, 1.0), max(high, 2.0), L2gradient=True)


@dataclass(frozen=True)
class ChamferMap:
    distance: np.ndarray  # float32 (H, W), pixels of the scaled image, capped at tau
    scale: float
    tau: float

    @classmethod
    def from_image(cls, linear: np.ndarray, scale: float, tau: float) -> ChamferMap:
        edges = canny_edges(linear, scale)
        distance = cv2.distanceTransform(np.where(edges > 0, 0, 255).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        return cls(np.minimum(distance, tau).astype(np.float32), scale, tau)

    def cost(self, pixels: np.ndarray) -> np.ndarray:
        """Per point: the capped squared distance (in full-resolution pixels) to the nearest
        edge; points outside the image cost the cap."""
        p = np.asarray(pixels, float) * self.scale
        h, w = self.distance.shape
        inside = (p[:, 0] >= 0) & (p[:, 0] <= w - 1) & (p[:, 1] >= 0) & (p[:, 1] <= h - 1) & np.all(np.isfinite(p), 1)
        d = np.full(len(p), self.tau, np.float32)
        if inside.any():
            q = p[inside].astype(np.float32)
            d[inside] = cv2.remap(self.distance, q[:, 0:1], q[:, 1:2], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)[:, 0]
        return (d.astype(float) / self.scale) ** 2


def smoothed(linear: np.ndarray) -> np.ndarray:
    """What edge_offsets samples: the linear grey image through a 3 x 3 median (it removes
    isolated bright pixels, the path tracer's fireflies and hot pixels, and keeps a straight
    step where it is) and a Gaussian of PRESMOOTH_SIGMA_PX (float32)."""
    image = cv2.medianBlur(np.ascontiguousarray(linear, np.float32), 3)
    return cv2.GaussianBlur(image, (0, 0), PRESMOOTH_SIGMA_PX)


@dataclass(frozen=True)
class EdgeOffsets:
    offset: np.ndarray    # (N,) pixels along the normal from the prediction to the measured edge
    strength: np.ndarray  # (N,) |derivative| at the edge, per pixel of offset (intensity units)
    contrast: np.ndarray  # (N,) strength over the image's derivative noise (derivative_noise)
    polarity: np.ndarray  # (N,) +1 where the image gets brighter along the normal, -1 darker
    valid: np.ndarray     # (N,) bool: inside the image, an interior extremum


def derivative_noise(image: np.ndarray, samples: int = 4000, seed: int = 0) -> float:
    """The typical |derivative| edge_offsets sees where there is no edge: its median over
    random points and directions (most of an image is not an edge), times 1.4826 (a
    Gaussian's sigma from its median absolute value)."""
    rng = np.random.default_rng(seed)
    h, w = image.shape
    pixels = np.stack([rng.uniform(8, w - 9, samples), rng.uniform(8, h - 9, samples)], 1)
    angle = rng.uniform(0, np.pi, samples)
    profile = _profiles(image, pixels, np.stack([np.cos(angle), np.sin(angle)], 1), 1.0)[0]
    derivative = (profile[:, 2:] - profile[:, :-2]) / (2 * STRIP_STEP_PX)
    return float(1.4826 * np.median(np.abs(derivative)))


def _profiles(image: np.ndarray, pixels: np.ndarray, normals: np.ndarray, half_window: float):
    """Intensity across each edge at offsets ``across``, averaged along it; which strips lie inside."""
    tangents = np.stack([-normals[:, 1], normals[:, 0]], 1)
    across = np.arange(-half_window - STRIP_STEP_PX, half_window + STRIP_STEP_PX + 1e-9, STRIP_STEP_PX)
    along = np.arange(-STRIP_HALF_WIDTH_PX, STRIP_HALF_WIDTH_PX + 1e-9, STRIP_STEP_PX)
    grid = (pixels[:, None, None, :] + across[None, :, None, None] * normals[:, None, None, :]
            + along[None, None, :, None] * tangents[:, None, None, :])
    h, w = image.shape
    inside = np.all((grid[..., 0] >= 0) & (grid[..., 0] <= w - 1) & (grid[..., 1] >= 0) & (grid[..., 1] <= h - 1), axis=(1, 2))
    values = bilinear(image, grid.reshape(-1, 2), interpolation=cv2.INTER_CUBIC)
    return values.reshape(len(pixels), len(across), len(along)).mean(axis=2), across, inside


def bilinear(image: np.ndarray, xy: np.ndarray, row: int = 1024, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
    """``image`` (H, W) at the points ``xy`` (N, 2), bilinear (or ``interpolation``), edges
    replicated (cv2.remap, whose maps must stay under 32767 rows: the points are laid out
    ``row`` to a row)."""
    n = len(xy)
    padded = np.zeros((-(-n // row) * row, 2), np.float32)
    padded[:n] = xy
    maps = padded.reshape(-1, row, 2)
    values = cv2.remap(np.ascontiguousarray(image, np.float32), maps[..., 0], maps[..., 1], interpolation,
                       borderMode=cv2.BORDER_REPLICATE)
    return values.reshape(-1)[:n]


def edge_offsets(image: np.ndarray, pixels: np.ndarray, normals: np.ndarray, half_window: float,
                 sign: np.ndarray | None = None, noise: float | None = None) -> EdgeOffsets:
    """The edge nearest in strength along each normal: for every predicted edge pixel (N, 2)
    and unit normal (N, 2), the offset in [-half_window, half_window] of the steepest point of
    ``image`` (the smoothed linear grey image). ``sign`` (N,), when given, keeps only
    extrema of that sign of the derivative (the edge's polarity, e.g. from a render).
    ``noise``: derivative_noise of the image, the unit of ``contrast`` (default: measured)."""
    pixels = np.asarray(pixels, float)
    normals = np.asarray(normals, float)
    profile, across, inside = _profiles(image, pixels, normals, half_window)
    derivative = (profile[:, 2:] - profile[:, :-2]) / (2 * STRIP_STEP_PX)     # at across[1:-1]
    score = derivative * sign[:, None] if sign is not None else np.abs(derivative)
    positions = across[1:-1]
    k = np.argmax(score, axis=1)
    rows = np.arange(len(pixels))
    interior = (k > 0) & (k < score.shape[1] - 1)
    kc = np.clip(k, 1, score.shape[1] - 2)
    top = score[rows, kc]
    lobe = np.abs(positions[None, :] - positions[kc][:, None]) <= LOBE_HALF_WIDTH_PX
    weight = np.where(lobe, np.maximum(score - LOBE_FLOOR * top[:, None], 0.0), 0.0)
    offset = (weight * positions).sum(1) / np.maximum(weight.sum(1), 1e-30)
    valid = inside & interior & (top > 0) & (np.abs(offset) <= half_window)
    peak = derivative[rows, kc]
    if noise is None:
        noise = derivative_noise(image)
    contrast = np.abs(peak) / max(noise, 1e-12 * float(np.max(np.abs(peak), initial=1.0)))
    return EdgeOffsets(offset, np.abs(peak), contrast, np.sign(peak), valid)

"""The CD's rim found in an image: an ellipse fitted to the edges of its disk.

Edges of the CD's disk are found along normals of the expected rim (the camera's
projection of the rim circle), at the strongest brightness gradient (parabolic sub-pixel
peak), and an ellipse is fitted to them (cv2.fitEllipse, outliers over
``RIM_OUTLIER_PX`` dropped), so a photo's CD is located from the photo itself and a
wrong pose shows up as an offset.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import cv2
import numpy as np

from reports.fringes.band_edges import MAD_TO_SIGMA

RIM_SEARCH_PX = 8.0  # how far from the expected rim the photo's rim is looked for
RIM_OUTLIER_PX = 1.5
RIM_MIN_POINTS = 24


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


def outward_normals(curve: np.ndarray) -> np.ndarray:
    """Unit normals (N, 2) of a closed curve of pixels (N, 2), pointing away from its centroid
    (central differences of the neighbours)."""
    tangent = np.roll(curve, -1, axis=0) - np.roll(curve, 1, axis=0)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    return normal * np.sign(np.einsum("ij,ij->i", normal, curve - curve.mean(axis=0)))[:, None]


def rim_points(image: np.ndarray, expected: np.ndarray, search_px: float = RIM_SEARCH_PX) -> np.ndarray:
    """Sub-pixel rim points: along the normal of the expected rim curve (pixels (N, 2), closed),
    the strongest brightness gradient within ``search_px`` (parabolic peak)."""
    grey = _grey(image)
    normal = outward_normals(expected)
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


def ellipse_residual(points: np.ndarray, rim: Rim) -> np.ndarray:
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
        residual = np.abs(ellipse_residual(points, rim))
        keep = residual <= max(RIM_OUTLIER_PX, 3 * MAD_TO_SIGMA * float(np.median(residual[keep])))
    assert rim is not None
    rim.rms_px = float(np.sqrt(np.mean(ellipse_residual(points[keep], rim) ** 2)))
    rim.points = int(keep.sum())
    return rim

"""The CD's disk unwrapped to (radius, azimuth) about its centre, through a camera.

A polar grid is a set of points on the grating plane, ``centre + rho R (cos phi e1 +
sin phi e2)`` (rho: the fraction of the outer radius R, phi: the azimuth from the CD's
frame axis e1, renderer.placement.frame_to), projected into the image with the camera's
lens model (renderer.camera.CameraModel.project, distortion included). Photo, render
and prediction are all sampled on the same grid, so a fringe found at the same grid
position is at the same image position, and a difference in grid coordinates is a
difference in pixels. An optional affine map moves the grid onto another image's CD (the
rim ellipse found there), which gives positions relative to that image's own CD.

Two grids serve the band edges (reports.fringes.band_edges): circles (few radii, fine azimuth
steps: edges along circles, where bands are sharp) and radii (few azimuths, fine radius
steps).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from renderer.camera import CameraModel

CIRCLE_COUNT = 16  # radii sampled along circles
CIRCLE_STEP_PX = 0.35  # arc step at the outer rim
RADIUS_STEP_PX = 0.35  # step along a radius at its most foreshortened
RADIUS_AZIMUTH_STEP_DEG = 2.0
RIM_MARGIN = 0.06  # fraction of the outer radius kept clear of the rim and the hole
ACROSS_PX = 3.0  # radius profiles are medians over +-3 px across them (in azimuth)
CIRCLE_ACROSS_PX = 3.0  # circle profiles over +-3 px along the radius (a band's edges run nearly radially). +-6 px
# was tried on cornell_cd_view2 at 640 x 480: photo-render p95 0.72 against 0.76 px, but at 320 x 240 it spans 20 %
# of the radius and blurs the hue, which changes along it
ACROSS_SPACING_PX = 0.75  # between the copies of a grid moved across its profiles


@dataclass(frozen=True)
class PolarGrid:
    """Grid points (radii, azimuths) on the CD and their pixel positions (radii, azimuths, 2)."""

    kind: str  # "circle": profiles along azimuth at fixed radius; "radius": along radius at fixed azimuth
    radii: np.ndarray  # fractions of the outer radius
    azimuths_deg: np.ndarray
    pixels: np.ndarray
    across: np.ndarray | None = None  # (K, radii, azimuths, 2): the grid moved across the profiles, for a median

    def profiles_axis(self) -> int:
        """The axis of ``pixels`` along which a profile runs (1: azimuth, 0: radius)."""
        return 1 if self.kind == "circle" else 0

    def step_px(self) -> np.ndarray:
        """Pixel distance between neighbouring samples along the profiles, same shape as the grid."""
        axis = self.profiles_axis()
        d = np.linalg.norm(np.diff(self.pixels, axis=axis), axis=-1)
        if self.kind == "circle":  # periodic: the last sample's step closes the circle
            d = np.concatenate([d, np.linalg.norm(self.pixels[:, :1] - self.pixels[:, -1:], axis=-1)], axis=1)
        else:
            d = np.concatenate([d, d[-1:]], axis=0)
        return d

    def point(self, profile: int, position: float) -> np.ndarray:
        """Pixel position at fractional ``position`` along profile ``profile``."""
        line = self.pixels[profile] if self.kind == "circle" else self.pixels[:, profile]
        n = len(line)
        i = int(np.floor(position)) % n
        t = position - np.floor(position)
        j = (i + 1) % n if self.kind == "circle" else min(i + 1, n - 1)
        return (1 - t) * line[i] + t * line[j]

    def profile_label(self, profile: int) -> float:
        """The fixed coordinate of a profile: rho for circles, azimuth (deg) for radii."""
        return float(self.radii[profile] if self.kind == "circle" else self.azimuths_deg[profile])

    def coordinate(self, position: float) -> float:
        """The running coordinate at a fractional position: azimuth (deg) for circles, rho for radii."""
        axis = self.azimuths_deg if self.kind == "circle" else self.radii
        step = axis[1] - axis[0]
        return float(axis[0] + position * step)

    @property
    def profile_count(self) -> int:
        return len(self.radii) if self.kind == "circle" else len(self.azimuths_deg)


def cd_points(cd, radii: np.ndarray, azimuths_deg: np.ndarray) -> np.ndarray:
    """World points (radii, azimuths, 3) on the grating plane of ``cd`` (renderer.trace.prediction.CDGeometry)."""
    phi = np.radians(azimuths_deg)
    direction = np.cos(phi)[:, None] * cd.frame[:, 0] + np.sin(phi)[:, None] * cd.frame[:, 1]
    return cd.center[None, None] + (np.asarray(radii)[:, None, None] * cd.outer_radius) * direction[None]


def _pixels(camera: CameraModel, cd, radii: np.ndarray, azimuths_deg: np.ndarray, affine: np.ndarray | None) -> np.ndarray:
    points = cd_points(cd, radii, azimuths_deg)
    pixels = camera.project(points.reshape(-1, 3)).reshape(len(radii), len(azimuths_deg), 2)
    if affine is not None:
        pixels = pixels @ affine[:, :2].T + affine[:, 2]
    return pixels


def grid(camera: CameraModel, cd, kind: str, radii: np.ndarray, azimuths_deg: np.ndarray,
         affine: np.ndarray | None = None, across_px: float = 0.0,
         rho_limits: tuple[float, float] = (0.0, np.inf)) -> PolarGrid:
    """The grid's pixels through ``camera``; ``affine`` (2 x 3) then moves them (another image's CD).

    ``across_px`` > 0 adds copies of the grid moved across the profiles (radius for circles,
    azimuth for radii) by up to +-``across_px`` pixels, ``ACROSS_SPACING_PX`` apart: samples whose
    median is robust to a render's outliers and to a photo's noise, and which barely blur an
    edge that runs across the profile (a band's edge along a circle runs along the radius).
    Circles moved along the radius stay on the disk (between ``rho_limits``)."""
    radii, azimuths_deg = np.asarray(radii, float), np.asarray(azimuths_deg, float)
    pixels = _pixels(camera, cd, radii, azimuths_deg, affine)
    across = None
    if across_px > 0:
        radius_px = max(rim_radius_px(camera, cd), 4.0)
        count = 2 * int(round(across_px / ACROSS_SPACING_PX)) + 1
        shifts = np.linspace(-1.0, 1.0, count) * across_px / radius_px  # in rho, or in radians of azimuth
        if kind == "circle":
            across = np.stack([_pixels(camera, cd, np.clip(radii + d, *rho_limits), azimuths_deg, affine) for d in shifts])
        else:
            across = np.stack([_pixels(camera, cd, radii, azimuths_deg + np.degrees(d / np.maximum(radii.mean(), 1e-3)),
                                       affine) for d in shifts])
    return PolarGrid(kind, radii, azimuths_deg, pixels, across)


def rim_radius_px(camera: CameraModel, cd) -> float:
    """The CD's largest apparent radius in pixels (its rim's semi-major axis, roughly)."""
    rim = camera.project(cd.rim_points())
    return float(np.max(np.linalg.norm(rim - rim.mean(axis=0), axis=1)))


def standard_grids(camera: CameraModel, cd, affine: np.ndarray | None = None) -> tuple[PolarGrid, PolarGrid]:
    """The circle grid and the radius grid for this camera's view of the CD."""
    radius_px = max(rim_radius_px(camera, cd), 4.0)
    rho_in = cd.inner_radius / cd.outer_radius + RIM_MARGIN
    rho_out = 1.0 - RIM_MARGIN
    azimuth_count = int(np.ceil(2 * np.pi * radius_px / CIRCLE_STEP_PX / 8)) * 8
    inside = (cd.inner_radius / cd.outer_radius + 0.5 * RIM_MARGIN, 1.0 - 0.5 * RIM_MARGIN)
    circles = grid(camera, cd, "circle", np.linspace(rho_in, rho_out, CIRCLE_COUNT),
                   np.arange(azimuth_count) * (360.0 / azimuth_count), affine, CIRCLE_ACROSS_PX, inside)
    radius_count = int(np.ceil((rho_out - rho_in) * radius_px / RADIUS_STEP_PX)) + 1
    radii = grid(camera, cd, "radius", np.linspace(rho_in, rho_out, radius_count),
                 np.arange(0.0, 360.0, RADIUS_AZIMUTH_STEP_DEG), affine, ACROSS_PX)
    return circles, radii


def sample(image: np.ndarray, polar: PolarGrid, robust: bool = False) -> np.ndarray:
    """Bilinear samples of ``image`` (H, W) or (H, W, C) at the grid: (radii, azimuths[, C]);
    points outside the image are nan. ``robust``: the median over the grid's copies across
    the profiles (PolarGrid.across), where it has them."""
    if robust and polar.across is not None:
        return np.median(np.stack([_sample_at(image, pixels) for pixels in polar.across]), axis=0)
    return _sample_at(image, polar.pixels)


def sample_crop(crop: np.ndarray, origin: tuple[int, int], frame: tuple[int, int], polar: PolarGrid,
                robust: bool = False) -> np.ndarray:
    """``sample`` of an image that is zero outside ``crop`` (h, w, C) placed at ``origin`` (x0, y0)
    in a frame of ``frame`` (H, W): the same values, without making the whole frame."""
    x0, y0 = origin
    copies = polar.across if robust and polar.across is not None else polar.pixels[None]
    values = []
    for pixels in copies:
        v = _sample_at(crop, pixels - np.array([x0, y0], float), fill=0.0)
        outside = ((pixels[..., 0] < 0) | (pixels[..., 1] < 0) | (pixels[..., 0] > frame[1] - 1)
                   | (pixels[..., 1] > frame[0] - 1))
        v[outside] = np.nan
        values.append(v)
    return np.median(np.stack(values), axis=0) if len(values) > 1 else values[0]


def _sample_at(image: np.ndarray, pixels: np.ndarray, fill: float | None = None) -> np.ndarray:
    map_x = pixels[..., 0].astype(np.float32)
    map_y = pixels[..., 1].astype(np.float32)
    values = cv2.remap(np.ascontiguousarray(image, dtype=np.float32), map_x, map_y, cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan if fill is None else fill)
    values = values.astype(float)
    if fill is None:
        h, w = image.shape[:2]
        values[(map_x < 0) | (map_y < 0) | (map_x > w - 1) | (map_y > h - 1)] = np.nan
    return values

"""The trace's geometry, written once: rays against planes and discs, the box's walls, the
light's rectangle, and the grating equation for a back-traced ray.

The planner (renderer.trace.planner), the prediction (renderer.trace.prediction), the
calibration's scene model (calibration.pose.scene_model) and the CD's shadow
(reports.fringes.cd_shadow) all take their geometry from here, in numpy, without Mitsuba.

Ray against plane in closed form: a ray ``o + t d`` meets the plane through ``p`` with normal
``n`` at ``t = ((p - o) . n) / (d . n)`` [Pharr 2023, Sec. 6.1.2]; against a disc or an
annulus, the same point's distance from the centre [Pharr 2023, Sec. 6.5.2].

The grating equation for a ray traced back from the camera: the wave leaving the grating in
order (m, n) toward the camera has the tangential wave vector ``n_out omega_t`` (over k0), so
the incident wave that feeds it has ``k_inc = n_out omega_t - ORDER_SIGN (m lambda / Lambda_x,
n lambda / Lambda_y)`` [Lange 2021, Eq. 2], the sign of workbench.core.conventions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderer.placement import box_points_m
from renderer.scene import SceneSpec, box_scale, cornell_data
from workbench.core.conventions import ORDER_SIGN

BOX_WALLS = ("floor_white", "ceiling_white", "back_wall_white", "right_wall_green", "left_wall_red")


def ray_plane_t(origin: np.ndarray, directions: np.ndarray, point: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """The distance ``t`` along each ray ``origin + t directions`` to the plane through ``point``
    with ``normal`` [Pharr 2023, Sec. 6.1.2].

    Parameters
    ----------
    origin : (3,) or (N, 3) array
        The rays' start points.
    directions : (N, 3) array
        The rays' directions (not necessarily unit: ``t`` is then in their lengths).
    point, normal : (3,) arrays
        A point on the plane and its normal.

    Returns
    -------
    (N,) array
        ``t``; infinite or NaN for rays parallel to the plane.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        return ((point - origin) @ normal) / (directions @ normal)


def plane_hits(origin: np.ndarray, rays: np.ndarray, center: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where rays meet a plane ahead of them.

    Parameters
    ----------
    origin : (3,) or (N, 3) array
        The rays' start points.
    rays : (N, 3) array
        Their directions.
    center, normal : (3,) arrays
        A point on the plane and its normal.

    Returns
    -------
    points : (N, 3) array
        The hit points (the origin for rays that miss).
    ok : (N,) bool array
        Which rays meet the plane at ``t > 0``.
    """
    t = ray_plane_t(origin, rays, center, normal)
    ok = np.isfinite(t) & (t > 0)
    return origin + rays * np.where(ok, t, 0.0)[:, None], ok


def annulus_hits(origin: np.ndarray, directions: np.ndarray, center: np.ndarray, normal: np.ndarray,
                 inner: float, outer: float, t_min: float, t_max: np.ndarray | float) -> np.ndarray:
    """Which rays meet an annulus (a disc with a hole) at ``t_min < t < t_max`` [Pharr 2023, Sec. 6.5.2].

    Parameters
    ----------
    origin, directions : arrays
        The rays, as ``ray_plane_t`` takes them.
    center, normal : (3,) arrays
        The annulus's centre and normal.
    inner, outer : float
        Its radii (metres).
    t_min : float
        Hits nearer than this are not counted (a surface does not hide itself).
    t_max : float or (N,) array
        Hits at or beyond this are not counted (the segment's end).

    Returns
    -------
    (N,) bool array
    """
    t = ray_plane_t(origin, directions, center, normal)
    t = np.where(np.isfinite(t), t, -1.0)
    r = np.linalg.norm(origin + t[:, None] * directions - center, axis=1)
    return (t > t_min) & (t < t_max) & (r >= inner) & (r <= outer)


def box_walls(spec: SceneSpec) -> dict[str, np.ndarray]:
    """The box's five quads (4, 3) in metres by name, scaled to the scene's box
    (renderer.placement.box_points_m, the placement the Mitsuba scene uses)."""
    geometry = cornell_data()["geometry"]
    scale = box_scale(spec.box)
    return {name: box_points_m(geometry[name], scale) for name in BOX_WALLS}


@dataclass(frozen=True)
class LightRectangle:
    """The scene's ceiling light: a rectangle facing down (-y), centred at ``center`` (3,), with
    half-extents ``half`` (2,) along world x and z (metres)."""

    center: np.ndarray
    half: np.ndarray

    def corners(self) -> np.ndarray:
        """The four corners (4, 3), in order around the rectangle."""
        cx, cy, cz = self.center
        hx, hz = self.half
        return np.array([[cx - hx, cy, cz - hz], [cx + hx, cy, cz - hz], [cx + hx, cy, cz + hz], [cx - hx, cy, cz + hz]])

    def grid(self, count: int) -> np.ndarray:
        """Points (count**2, 3) spread evenly over the rectangle (cell centres)."""
        corners = self.corners()
        u = (np.arange(count) + 0.5) / count
        a, b = np.meshgrid(u, u, indexing="ij")
        ex, ez = corners[1] - corners[0], corners[3] - corners[0]
        return (corners[0] + a.reshape(-1, 1) * ex + b.reshape(-1, 1) * ez).reshape(-1, 3)

    def outline_points(self) -> np.ndarray:
        """The corners, the edges' midpoints and the centre (9, 3)."""
        offsets = np.array([[a, b] for a in (-1.0, 0.0, 1.0) for b in (-1.0, 0.0, 1.0)])
        return self.center[None] + np.stack(
            [offsets[:, 0] * self.half[0], np.zeros(len(offsets)), offsets[:, 1] * self.half[1]], 1)

    def hit_by(self, points: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Whether rays from ``points`` (N, 3) along ``directions`` (N, 3) meet the rectangle ahead of them."""
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (self.center[1] - points[:, 1]) / directions[:, 1]
        hit = points + directions * np.where(np.isfinite(t), t, 0.0)[:, None]
        inside = (np.abs(hit[:, 0] - self.center[0]) <= self.half[0]) & (np.abs(hit[:, 2] - self.center[2]) <= self.half[1])
        return (t > 0) & inside


def light_rectangle(spec: SceneSpec) -> LightRectangle:
    """The scene file's light (``light.center``, ``light.size`` along x and z) as a rectangle."""
    return LightRectangle(np.asarray(spec.light.center, float), np.asarray(spec.light.size, float) / 2)


def light_corners(spec: SceneSpec) -> np.ndarray:
    """The light rectangle's corners (4, 3): centred at ``light.center``, ``size`` along x and z."""
    return light_rectangle(spec).corners()


def incident_k(outgoing_t: np.ndarray, m: int, n: int, wavelength_nm: np.ndarray | float, period_um: tuple[float, ...],
               n_out: float = 1.0) -> np.ndarray:
    """The incident wave's tangential wave vector over k0 that feeds order (m, n) leaving along
    ``outgoing_t``: ``n_out outgoing_t - ORDER_SIGN (m lambda / Lambda_x, n lambda / Lambda_y)``
    [Lange 2021, Eq. 2].

    Parameters
    ----------
    outgoing_t : (N, 2) array
        The outgoing wave's unit direction's tangential components in the grating frame.
    m, n : int
        The order (``n`` is ignored for a 1D grating).
    wavelength_nm : float or (N,) array
        The vacuum wavelength (nm), one for all rows or one per row.
    period_um : tuple of float
        The grating's period(s) (micrometres): one for 1D, two for 2D.
    n_out : float
        The refractive index of the medium the order leaves into.

    Returns
    -------
    (N, 2) array
        ``(kx, ky) / k0``; the incident wave exists (propagates in a medium of index n_in)
        where ``|k| < n_in``.
    """
    k = n_out * np.asarray(outgoing_t, float)
    k[:, 0] -= ORDER_SIGN * m * wavelength_nm / (1000.0 * period_um[0])
    if len(period_um) > 1:
        k[:, 1] -= ORDER_SIGN * n * wavelength_nm / (1000.0 * period_um[1])
    return k

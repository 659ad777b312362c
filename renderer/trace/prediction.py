"""Where the grating equation puts the CD's lit bands, for a camera, independent of the renderer.

For every camera pixel that sees the CD, every diffraction order m and every wavelength
(5 nm apart over the camera's range) the camera ray is sent back through the grating
equation and tested against the ceiling light's rectangle; a pixel of order m is lit at
lambda when that ray reaches the light. Nothing here uses Mitsuba:
its geometry checks the renderer from outside; its brightness weights (below) come from the
RCWA solution of the CD's structure, the renderer's physics input, not from the renderer.

The path, for one pixel (world frame, metres; the CD's frame is renderer.placement.frame_to):

1. The camera ray (renderer.camera.CameraModel, OpenCV's model with distortion) meets the
   CD's flat polycarbonate top (``CD_TOP_THICKNESS_M`` above the grating) and refracts
   (Snell's law; the top's index is the scene's: n(lambda) of polycarbonate, or its mean
   over 360-830 nm when the scene's top is not dispersive, as renderer.dielectric does),
   then meets the grating plane at p, which must lie on the annulus.
2. The grating axis at p is radial, computed from p and the CD's centre (the CD's
   circular tracks; not a mesh triangle's direction).
3. The grating equation ([Lange 2021, Eq. 2], with the order sign of
   workbench.core.conventions.ORDER_SIGN): tangential wave vectors over k0 satisfy
   ``k_out = k_inc + ORDER_SIGN m lambda / Lambda x_hat``. The flat top keeps the
   tangential wave vector, so ``k_out`` is the tangential part of the direction toward the
   camera in air, and ``k_inc = k_out - ORDER_SIGN m lambda / Lambda x_hat``
   (renderer.trace.geometry.incident_k, in air: both indices 1); the wave exists where
   ``|k_inc| < 1``.
4. The light lies against the incident wave (renderer.trace.planner.source_rays). Inside the
   top the back-traced ray climbs ``CD_TOP_THICKNESS_M`` at the refracted angle, so it
   leaves the top beside p; from there it must hit the light's rectangle
   (renderer.trace.geometry.LightRectangle.hit_by; occlusion by other objects is not tested).

Per pixel, order and channel the lit fraction is the camera-sensitivity-weighted share
of the light's spectrum that arrives, weighted by what the light meets on the way:
``sum_lambda S_c E lit w eta T_in T_out / (c_m sum_lambda S_c E)``, with E the light's
spectrum, w the light's emission profile cos^n at the angle the ray leaves it (1 for a
Lambertian light), and (``weighting="efficiency"``, the default):

* eta_m(lambda, theta, phi): the order's RCWA diffraction efficiency for unpolarized light
  at the incident wave's direction inside the grating's superstrate, read from the scene's
  efficiency table (renderer.trace.efficiency_weights: how the table is read);
* T_in, T_out: the flat top's Fresnel transmission, unpolarized, for the camera's ray and
  for the light's (renderer.trace.efficiency_weights.fresnel_transmission);
* c_m: the order's mean of eta T_in T_out over its lit (pixel, wavelength) pairs (weighted
  by S_c E w; ``Prediction.order_efficiency``), so that a lit fraction stays a share of
  the light's spectrum (about 0..1) and reports.fringes.band_edges' thresholds keep their meaning.

Each factor is the unpolarized mean on its own, as the renderer's BWDF and dielectric take
them (the top's Fresnel transmission partly polarizes the light the grating then sees; that
correlation is left out by both).

Why the efficiency matters, as measured: renderer.trace.efficiency_weights.
``weighting="geometric"`` leaves eta and T out (the lit share of the spectrum alone; the
edges of a grating of flat efficiency).

With a non-dispersive top (``dispersion = false``) the renderer refracts at the top's mean
index and diffracts under it with the same index (the BWDF's ``superstrate_index``), so
the orders' directions in air are the dispersive top's, as here; before it did, its orders
left as if m lambda / Lambda were scaled by n_mean / n(lambda) (0.98 at 410 nm, 1.008 at
685 nm), which moved cornell_cd's radius edges by about -0.25 px against this prediction.

Pixels are supersampled (``SUPERSAMPLE`` per axis) and averaged, so a prediction is
pixel-integrated as a render and a photo are.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from rcwa.materials import material_from_spec
from rcwa.structure import load_structure
from renderer.camera import CameraModel
from renderer.camera_coverage import visible_range
from renderer.placement import frame_to
from renderer.scene import CD_TOP_THICKNESS_M, SPECTRAL_RANGE_NM, CDSpec, SceneSpec
from renderer.spectra import camera_sensitivities, light_spectrum
from renderer.trace.efficiency_weights import Efficiency, fresnel_transmission, scene_efficiency
from renderer.trace.geometry import incident_k, light_rectangle, plane_hits
from workbench.core.conventions import ORDER_SIGN
from workbench.core.errors import UserInputError

PREDICTION_STEP_NM = 5.0  # wavelengths sampled; a band edge moves about 0.5-1 px per 5 nm along a radius
SUPERSAMPLE = 2  # sub-pixel rays per axis: pixel-integrated like the images, 4 rays per pixel
BBOX_MARGIN_PX = 3
RIM_POINTS = 720
MAX_ORDER = 12  # |m| * lambda / Lambda < 2 bounds the propagating orders; 12 covers a 1.6 um period down to 270 nm
LIGHT_BOX_MARGIN = 0.05  # direction cosines; the top's lateral shift moves a direction by < 0.005


@dataclass(frozen=True)
class CDGeometry:
    """One CD: the grating plane's centre, its frame (columns e1, e2, normal), radii, top, period."""

    center: np.ndarray
    frame: np.ndarray
    inner_radius: float
    outer_radius: float
    top_thickness_m: float
    top_dispersive: bool
    period_um: float

    @property
    def normal(self) -> np.ndarray:
        return self.frame[:, 2]

    def top_index(self, wavelengths_nm: np.ndarray) -> np.ndarray:
        """The top's real index at ``wavelengths_nm``: n(lambda), or its mean over 360-830 nm
        (renderer.dielectric.mean_index: 1 nm steps, held constant beyond the data)."""
        pc = material_from_spec("polycarbonate")
        lo, hi = pc.wavelength_range_nm or SPECTRAL_RANGE_NM
        if self.top_dispersive:
            return np.real(pc.refractive_index(np.clip(wavelengths_nm, lo, hi)))
        grid = np.linspace(SPECTRAL_RANGE_NM[0], SPECTRAL_RANGE_NM[1], round(SPECTRAL_RANGE_NM[1] - SPECTRAL_RANGE_NM[0]) + 1)
        mean = float(np.real(pc.refractive_index(np.clip(grid, lo, hi))).mean())
        return np.full(np.shape(wavelengths_nm), mean)

    def rim_points(self, radius: float | None = None, count: int = RIM_POINTS, on_top: bool = False) -> np.ndarray:
        """World points (count, 3) on a circle about the centre (the outer rim by default)."""
        angles = np.linspace(0.0, 2 * np.pi, count, endpoint=False)
        r = self.outer_radius if radius is None else radius
        lift = self.top_thickness_m if on_top else 0.0
        return (self.center + lift * self.normal)[None] + r * (np.cos(angles)[:, None] * self.frame[:, 0]
                                                               + np.sin(angles)[:, None] * self.frame[:, 1])


def cd_geometry(spec: SceneSpec, index: int = 0) -> CDGeometry:
    """The geometry of the scene's CD ``index`` and its structure's period."""
    if not spec.cds:
        raise UserInputError("the scene has no CD: there are no fringes to measure", file=spec.source, field="cd")
    if not 0 <= index < len(spec.cds):
        raise UserInputError("no such CD in the scene", file=spec.source, field="cd", expected=f"0..{len(spec.cds) - 1}",
                             got=index)
    cd: CDSpec = spec.cds[index]
    structure = load_structure(cd.structure)
    if len(structure.period) != 1:
        raise UserInputError("the CD's structure is not a 1D grating (one period): its fringes are not radial bands",
                             file=spec.source, field=f"cd[{index}].structure", got=cd.structure)
    return CDGeometry(np.asarray(cd.center, float), frame_to(cd.normal, cd.rotation_deg), cd.inner_radius,
                      cd.outer_radius, CD_TOP_THICKNESS_M if cd.top_surface else 0.0, cd.dispersion,
                      float(structure.period[0]))

Weighting = Literal["efficiency", "geometric"]


def pixel_rays(camera: CameraModel, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The camera centre and unit world directions through pixel positions (CameraModel.pixel_rays)."""
    return camera.pixel_rays(pixels)


def _on_annulus(points: np.ndarray, cd: CDGeometry, lift: float = 0.0) -> np.ndarray:
    r = np.linalg.norm(points - (cd.center + lift * cd.normal), axis=1)
    return (r >= cd.inner_radius) & (r <= cd.outer_radius)


def trace_to_grating(origin: np.ndarray, rays: np.ndarray, cd: CDGeometry, top_index: float) -> tuple[np.ndarray, np.ndarray]:
    """Points (N, 3) where camera rays meet the grating after refracting into the top
    (Snell's law, vector form: t = eta d + (eta cos_i - cos_t) n, eta = 1 / n_top), and which
    rays reach the annulus from the camera's side through the top's annulus."""
    normal = cd.normal
    cos_i = -(rays @ normal)
    valid = cos_i > 0  # the camera looks at the grating's front
    if cd.top_thickness_m <= 0:
        points, ok = plane_hits(origin, rays, cd.center, normal)
        return points, valid & ok & _on_annulus(points, cd)
    entry, ok = plane_hits(origin, rays, cd.center + cd.top_thickness_m * normal, normal)
    valid &= ok & _on_annulus(entry, cd, cd.top_thickness_m)
    eta = 1.0 / top_index
    cos_t = np.sqrt(np.maximum(1.0 - eta**2 * (1.0 - cos_i**2), 0.0))
    inside = eta * rays + (eta * cos_i - cos_t)[:, None] * normal[None]
    points = entry + inside * (cd.top_thickness_m / np.maximum(cos_t, 1e-12))[:, None]
    return points, valid & _on_annulus(points, cd)


@dataclass
class Prediction:
    """Predicted lit fractions over a crop of the image (rows y0.., columns x0..).

    ``lit`` (orders, 3, h, w): per order and camera channel, the weighted share of the
    light's spectrum that reaches the pixel through that order (about 0..1; with the
    efficiency weighting relative to the order's mean efficiency ``order_efficiency``). ``on_cd`` (h, w):
    the share of the pixel's sub-rays that meet the grating. ``lit_nm`` (orders, 2, h, w):
    the shortest and longest lit wavelength at the pixel's centre ray (nan where unlit).
    """

    camera: CameraModel
    cd: CDGeometry
    orders: list[int]
    wavelengths_nm: np.ndarray
    weights: np.ndarray  # (3, wavelengths): each channel's normalised S_c E
    x0: int
    y0: int
    lit: np.ndarray
    on_cd: np.ndarray
    lit_nm: np.ndarray
    white: np.ndarray  # (3,) the light's camera RGB (light_white): the hue's white point
    seconds: float = 0.0
    weighting: str = "geometric"  # predict's ``weighting``
    order_efficiency: np.ndarray | None = None  # (orders,) c_m: each order's mean eta T_in T_out over its lit pairs
    efficiency_source: str | None = None  # the efficiency table read (its path), or None

    def full(self, image: np.ndarray, fill: float = 0.0) -> np.ndarray:
        """A crop-shaped array (..., h, w) placed in the camera's whole frame (..., H, W)."""
        out = np.full(image.shape[:-2] + (self.camera.height, self.camera.width), fill, dtype=float)
        h, w = image.shape[-2:]
        out[..., self.y0:self.y0 + h, self.x0:self.x0 + w] = image
        return out

    def channel_image(self, order: int) -> np.ndarray:
        """(3, H, W) lit fraction of one order over the whole frame."""
        return self.full(self.lit[self.orders.index(order)])

    def total(self) -> np.ndarray:
        """(3, H, W): every order's lit fraction summed (each order's band weighted alike)."""
        return self.full(self.lit.sum(axis=0))


def channel_weights(spec: SceneSpec, step_nm: float = PREDICTION_STEP_NM) -> tuple[np.ndarray, np.ndarray]:
    """Wavelengths over the camera's range (step ``step_nm``) and each channel's weights
    S_c(lambda) E(lambda), normalised to sum 1 (renderer.spectra's sensitivities and light spectrum)."""
    wavelengths, spectra = channel_spectra(spec, step_nm)
    return wavelengths, spectra / spectra.sum(axis=1, keepdims=True)


def light_white(spec: SceneSpec, step_nm: float = PREDICTION_STEP_NM) -> np.ndarray:
    """(3,) the camera RGB of the light on a white diffuser, up to one scale: sum_lambda S_c E.
    Dividing an image by it white-balances it on the light (the hue's white point)."""
    _, spectra = channel_spectra(spec, step_nm)
    return spectra.sum(axis=1) / spectra.sum()


def channel_spectra(spec: SceneSpec, step_nm: float = PREDICTION_STEP_NM) -> tuple[np.ndarray, np.ndarray]:
    """Wavelengths over the camera's range and S_c(lambda) E(lambda) (3, L), not normalised."""
    sens = camera_sensitivities(spec.camera.sensitivities)
    grid = np.unique(np.concatenate([w for w, _ in sens]))
    curves = np.stack([np.interp(grid, w, s, left=0, right=0) for w, s in sens])
    lo, hi = visible_range(grid, curves)
    wavelengths = np.arange(lo, hi + 1e-9, step_nm)
    light_wl, light_values = light_spectrum(spec.light.spectrum)
    emission = np.interp(wavelengths, light_wl, light_values, left=0.0, right=0.0)
    weights = np.stack([np.interp(wavelengths, w, s, left=0, right=0) for w, s in sens]) * emission[None]
    if np.any(weights.sum(axis=1) <= 0):
        raise UserInputError("a camera channel sees none of the light's spectrum", field="camera.sensitivities",
                             got=spec.camera.sensitivities)
    return wavelengths, weights


def cd_bbox(camera: CameraModel, cd: CDGeometry, margin: int = BBOX_MARGIN_PX) -> tuple[int, int, int, int] | None:
    """(x0, y0, x1, y1) of the pixels the CD's rim encloses (clipped to the frame), or None
    when the CD is behind the camera or wholly outside the image."""
    rims = np.concatenate([cd.rim_points(), cd.rim_points(on_top=True)])
    camera_points = rims @ camera.world_to_camera[:3, :3].T + camera.world_to_camera[:3, 3]
    if np.any(camera_points[:, 2] <= 0):
        return None
    px = camera.project(rims)
    x0, y0 = np.floor(px.min(axis=0)).astype(int) - margin
    x1, y1 = np.ceil(px.max(axis=0)).astype(int) + margin + 1
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, camera.width), min(y1, camera.height)
    return None if x1 <= x0 or y1 <= y0 else (int(x0), int(y0), int(x1), int(y1))


def _subpixels(x0: int, y0: int, x1: int, y1: int, s: int) -> np.ndarray:
    offsets = (np.arange(s) + 0.5) / s - 0.5
    ys, xs = np.arange(y0, y1), np.arange(x0, x1)
    yy = (ys[:, None] + offsets[None]).ravel()
    xx = (xs[:, None] + offsets[None]).ravel()
    grid_y, grid_x = np.meshgrid(yy, xx, indexing="ij")  # (h s, w s)
    return np.stack([grid_x.ravel(), grid_y.ravel()], axis=1)


def _candidate_orders(cd: CDGeometry, wavelengths: np.ndarray) -> list[int]:
    """Orders that propagate somewhere in the range: |m| lambda_min / Lambda < 2 (k_out, k_inc in the unit disk)."""
    limit = min(MAX_ORDER, math.floor(2 * cd.period_um * 1000.0 / float(wavelengths.min())))
    return list(range(-limit, limit + 1))


def _light_box(spec: SceneSpec, cd: CDGeometry, margin: float = LIGHT_BOX_MARGIN) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (lo, hi) of the light's directions seen from the CD, as tangential components
    along the CD's fixed axes (e1, e2): a cheap test that rules out most (pixel, wavelength)
    pairs before the exact one. From the rim and the centre to the light's corners and edge
    midpoints, widened by ``margin`` (the top's lateral shift and the direction set's curvature)."""
    corners = light_rectangle(spec).outline_points()
    starts = np.concatenate([cd.rim_points(count=64), cd.center[None]])
    d = corners[None] - starts[:, None]
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    k = np.stack([d @ cd.frame[:, 0], d @ cd.frame[:, 1]], axis=-1).reshape(-1, 2)
    return k.min(axis=0) - margin, k.max(axis=0) + margin


@dataclass
class _Light:
    """Which back-traced rays of one order reach the light, and what weighs them there."""

    lit: np.ndarray  # (N,) bool
    emission: np.ndarray  # (N,) the emission profile cos^n at the angle the ray leaves the light
    k: np.ndarray  # (N, 2) the incident wave's tangential wave vector over k0 in the radial frame

    def direction(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The incident wave's sin theta in air (|k|) and azimuth about the grating vector (degrees) at ``rows``."""
        k = self.k[rows]
        return np.hypot(k[:, 0], k[:, 1]), np.degrees(np.arctan2(k[:, 1], k[:, 0]))


def _light_hits(spec: SceneSpec, cd: CDGeometry, points: np.ndarray, axis: np.ndarray, ey: np.ndarray,
                omega_t: np.ndarray, m: int, lam: np.ndarray, top_index: float) -> _Light:
    """For order m at wavelengths ``lam`` (one per row): which points receive the light, the
    emission-profile weight there, and the incident wave's tangential wave vector (for its efficiency).

    The incident wave's tangential wave vector over k0, k = (kx, ky) in the radial frame
    (renderer.trace.geometry.incident_k in air), gives the light's direction without
    angles: -(kx x_hat + ky y_hat) + sqrt(1 - |k|^2) z_hat (renderer.trace.planner.source_rays,
    which takes theta = arcsin |k| and phi = atan2(ky, kx): the same vector to round-off, at a
    fraction of the cost on the fit's millions of pairs)."""
    k = incident_k(omega_t, m, 0, lam, (cd.period_um,))
    s2 = k[:, 0] ** 2 + k[:, 1] ** 2
    out = _Light(np.zeros(len(points), bool), np.zeros(len(points)), k)
    ok = s2 < 1.0
    if not ok.any():
        return out
    every = bool(ok.all())  # the candidate pairs are pre-selected toward the light: usually all propagate
    kx, ky, s2_ok = (k[:, 0], k[:, 1], s2) if every else (k[ok, 0], k[ok, 1], s2[ok])
    ax, ay, start = (axis, ey, points) if every else (axis[ok], ey[ok], points[ok])
    tangential = -(kx[:, None] * ax + ky[:, None] * ay)  # in air, toward the light
    source = tangential + np.sqrt(1.0 - s2_ok)[:, None] * cd.normal[None]
    if cd.top_thickness_m > 0:  # the back-traced ray climbs through the top before it leaves into air
        sin2_in = s2_ok / top_index**2
        # the tangential step per unit climb is tan(theta_in) along the tangential direction: |t| / (n cos theta_in)
        start = start + cd.top_thickness_m * (tangential / (top_index * np.sqrt(1.0 - sin2_in))[:, None]
                                              + cd.normal[None])
    hit = light_rectangle(spec).hit_by(start, source)
    emission = np.where(hit, np.maximum(source[:, 1], 0.0) ** (spec.light.cos_power or 0.0), 0.0)
    if every:
        out.lit, out.emission = hit, emission
    else:
        out.lit[ok], out.emission[ok] = hit, emission
    return out


@dataclass
class _Hits:
    """Camera rays that reach the grating, in its radial frame (for one top index)."""

    rows: np.ndarray  # indices of the rays
    points: np.ndarray
    axis: np.ndarray
    ey: np.ndarray
    omega_t: np.ndarray  # toward the camera, radial frame
    fixed_k: np.ndarray  # toward the camera, CD's fixed axes (e1, e2)
    fixed_axis: np.ndarray  # the radial axis in (e1, e2)


def _grating_hits(origin: np.ndarray, rays: np.ndarray, cd: CDGeometry, top_index: float) -> _Hits:
    points, on = trace_to_grating(origin, rays, cd, top_index)
    rows = np.flatnonzero(on)
    p = points[rows]
    radial = p - cd.center
    axis = radial / np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-300)
    ey = np.cross(cd.normal[None], axis)
    toward = -rays[rows]
    dot = lambda a, b: np.einsum("ij,ij->i", a, b)  # noqa: E731
    e1, e2 = cd.frame[:, 0], cd.frame[:, 1]
    return _Hits(rows, p, axis, ey, np.stack([dot(toward, axis), dot(toward, ey)], 1),
                 np.stack([toward @ e1, toward @ e2], 1), np.stack([axis @ e1, axis @ e2], 1))


def _candidate_pairs(hits: _Hits, m: int, lam: np.ndarray, period_um: float,
                     box: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(ray, wavelength index) pairs whose direction toward the light falls in ``box``.

    Along the CD's fixed axes k_inc = a + lambda b is linear in lambda (a: toward the camera,
    b = -ORDER_SIGN m x_hat / Lambda), so each axis bounds lambda to an interval; ``lam`` is sorted."""
    a = hits.fixed_k
    b = -ORDER_SIGN * m / (1000.0 * period_um) * hits.fixed_axis
    lower = np.full(len(a), lam[0])
    upper = np.full(len(a), lam[-1])
    for j in range(2):  # the light's side: lo <= -(a + lambda b) <= hi
        lo_k, hi_k = -box[1][j], -box[0][j]
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (lo_k - a[:, j]) / b[:, j], (hi_k - a[:, j]) / b[:, j]
        flat = b[:, j] == 0
        inside = (a[:, j] >= lo_k) & (a[:, j] <= hi_k)
        lower = np.maximum(lower, np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2)))
        upper = np.minimum(upper, np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2)))
    first = np.searchsorted(lam, lower, side="left")
    counts = np.maximum(np.searchsorted(lam, upper, side="right") - first, 0)
    rays = np.repeat(np.arange(len(a)), counts)
    offsets = np.arange(len(rays)) - np.repeat(np.cumsum(counts) - counts, counts)
    return rays, first[rays] + offsets


@dataclass
class _Events:
    """Lit (ray, wavelength) pairs of one order (``order`` indexes the orders asked for), or with
    ``order`` -1 the rays that reach the grating (``rows`` only)."""

    order: int
    rows: np.ndarray
    lam_index: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    emission: np.ndarray = field(default_factory=lambda: np.zeros(0))  # the light's emission profile
    factor: np.ndarray = field(default_factory=lambda: np.zeros(0))  # eta T_in T_out (1 for geometric weighting)


def _lit_events(spec: SceneSpec, cd: CDGeometry, origin: np.ndarray, rays: np.ndarray, orders: list[int],
                wavelengths: np.ndarray, efficiency: Efficiency | None = None) -> Iterator[_Events]:
    """Every order's lit pairs, and once per top index the rays that reach the grating.
    With ``efficiency``, each pair's factor is the order's efficiency at its incident direction
    times the top's Fresnel transmission for the camera's ray and the light's (module docstring)."""
    top_indices = cd.top_index(wavelengths)
    box = _light_box(spec, cd)
    for index in np.unique(top_indices):  # one index (a non-dispersive top) or one per wavelength
        hits = _grating_hits(origin, rays, cd, float(index))
        yield _Events(-1, hits.rows)
        lam_index = np.flatnonzero(top_indices == index)
        lam = wavelengths[lam_index]
        camera_in = np.ones(len(hits.rows))
        if efficiency is not None and cd.top_thickness_m > 0:
            camera_in = fresnel_transmission(np.sqrt(np.maximum(1.0 - (hits.omega_t**2).sum(axis=1), 0.0)), float(index))
        for i, m in enumerate(orders):
            ray, wl = _candidate_pairs(hits, m, lam, cd.period_um, box)
            if not len(ray):
                continue
            light = _light_hits(spec, cd, hits.points[ray], hits.axis[ray], hits.ey[ray], hits.omega_t[ray], m,
                                lam[wl], float(index))
            if not light.lit.any():
                continue
            lit = light.lit
            factor = np.ones(int(lit.sum()))
            if efficiency is not None:
                sin_air, phi_deg = light.direction(lit)
                factor = efficiency(m, lam[wl[lit]], sin_air, phi_deg) * camera_in[ray[lit]]
                if cd.top_thickness_m > 0:
                    factor *= fresnel_transmission(np.sqrt(1.0 - sin_air**2), float(index))
            yield _Events(i, hits.rows[ray[lit]], lam_index[wl[lit]], light.emission[lit], factor)


def lit_table(spec: SceneSpec, camera: CameraModel, pixels: np.ndarray, order: int, *, cd_index: int = 0,
              step_nm: float = PREDICTION_STEP_NM) -> tuple[np.ndarray, np.ndarray]:
    """Wavelengths (L,) and, for rays through the exact ``pixels`` (N, 2), which are lit by ``order`` (N, L)."""
    cd = cd_geometry(spec, cd_index)
    wavelengths, _ = channel_weights(spec, step_nm)
    origin, rays = pixel_rays(camera, pixels)
    table = np.zeros((len(pixels), len(wavelengths)), bool)
    for events in _lit_events(spec, cd, origin, rays, [order], wavelengths):
        if events.order >= 0:
            table[events.rows, events.lam_index] = True
    return wavelengths, table


def predict(spec: SceneSpec, camera: CameraModel | None = None, *, cd_index: int = 0, supersample: int = SUPERSAMPLE,
            step_nm: float = PREDICTION_STEP_NM, weighting: Weighting = "efficiency",
            efficiency: Efficiency | None = None, geometry: CDGeometry | None = None) -> Prediction:
    """The lit fractions of every order over the CD's pixels for ``camera`` (the scene's by default).

    ``weighting``: ``"efficiency"`` weighs each lit (pixel, wavelength) by the order's
    efficiency and the top's Fresnel transmission (module docstring), from ``efficiency``
    (the scene's table by default: scene_efficiency); ``"geometric"`` by the light's spectrum
    and emission profile alone. ``geometry``: the CD's geometry in place of the scene's
    (the scene fit's changed period). Raises UserInputError when the CD is not in the camera's view."""
    started = time.perf_counter()
    camera = camera or spec.camera.model
    cd = geometry if geometry is not None else cd_geometry(spec, cd_index)
    wavelengths, weights = channel_weights(spec, step_nm)
    box = cd_bbox(camera, cd)
    if box is None:
        raise UserInputError("the camera does not see the CD (it projects outside the image or lies behind the camera)",
                             file=spec.source, field=f"cd[{cd_index}].center")
    if weighting not in ("efficiency", "geometric"):
        raise ValueError(f"weighting must be 'efficiency' or 'geometric', not {weighting!r}")
    if weighting == "efficiency" and efficiency is None:
        efficiency = scene_efficiency(spec, cd_index)
    x0, y0, x1, y1 = box
    h, w, s = y1 - y0, x1 - x0, supersample
    pixels = _subpixels(x0, y0, x1, y1, s)
    origin, rays = pixel_rays(camera, pixels)
    orders = _candidate_orders(cd, wavelengths)
    lit_sum = np.zeros((len(orders), 3, len(pixels)))
    plain = np.zeros(len(orders))  # sum of S_c E w over each order's lit pairs (all channels) ...
    weighed = np.zeros(len(orders))  # ... and of S_c E w eta T_in T_out: their ratio is c_m
    lo_nm = np.full((len(orders), len(pixels)), np.inf)
    hi_nm = np.full((len(orders), len(pixels)), -np.inf)
    hit_any = np.zeros(len(pixels), bool)
    for ev in _lit_events(spec, cd, origin, rays, orders, wavelengths, efficiency if weighting == "efficiency" else None):
        i = ev.order
        if i < 0:
            hit_any[ev.rows] = True
            continue
        spectral = weights[:, ev.lam_index] * ev.emission  # (3, pairs)
        for c in range(3):
            np.add.at(lit_sum[i, c], ev.rows, spectral[c] * ev.factor)
        plain[i] += spectral.sum()
        weighed[i] += (spectral * ev.factor).sum()
        np.minimum.at(lo_nm[i], ev.rows, wavelengths[ev.lam_index])
        np.maximum.at(hi_nm[i], ev.rows, wavelengths[ev.lam_index])
    keep = [i for i in range(len(orders)) if lit_sum[i].any()]
    scale = np.array([weighed[i] / plain[i] for i in keep])  # c_m: the order's mean eta T_in T_out
    lit = lit_sum[keep].reshape(len(keep), 3, h, s, w, s).mean(axis=(3, 5)) / scale.reshape(-1, 1, 1, 1)
    on_cd = hit_any.reshape(h, s, w, s).mean(axis=(1, 3))
    lo_img = lo_nm[keep].reshape(len(keep), h, s, w, s)
    hi_img = hi_nm[keep].reshape(len(keep), h, s, w, s)
    c = s // 2  # the sub-ray at the pixel's centre (odd s) or just past it (even s)
    lit_nm = np.stack([lo_img[:, :, c, :, c], hi_img[:, :, c, :, c]], axis=1)
    lit_nm = np.where(np.isfinite(lit_nm), lit_nm, np.nan)
    return Prediction(camera, cd, [orders[i] for i in keep], wavelengths, weights, x0, y0, lit, on_cd, lit_nm,
                      light_white(spec, step_nm), time.perf_counter() - started, weighting, scale,
                      efficiency.source if efficiency is not None and weighting == "efficiency" else None)

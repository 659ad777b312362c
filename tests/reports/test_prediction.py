"""renderer/trace/prediction.py: the grating equation's lit bands, checked against a forward model.

The prediction traces backward (camera -> CD -> light). These tests go forward instead:
a point of the light, a wavelength and an order fix where on the CD the diffracted ray
reaches the camera (solved here with scipy from the grating equation alone, Lange et al.
2021 Eq. 2 with workbench.core.conventions.order_kx's sign); the prediction must say that
pixel is lit at that wavelength, and for a point on the light's edge the lit wavelengths
must end there.
"""

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import fsolve

from renderer.camera import CameraModel
from renderer.render import with_resolution
from renderer.scene import load_scene
from renderer.trace import prediction
from workbench.core.conventions import order_kx
from workbench.core.errors import UserInputError

RESOLUTION = (160, 120)  # small: the geometry does not depend on the pixel count
STEP_NM = prediction.PREDICTION_STEP_NM
SNELL_TOLERANCE = 1e-12  # n1 sin1 = n2 sin2 in float64
FORWARD_SOLVE_TOLERANCE = 1e-10  # the forward solution satisfies the grating equation to round-off
EDGE_TOLERANCE_NM = STEP_NM + 1e-6  # the lit set ends at the sampled wavelength next to the forward edge's


def _scene(top: bool = False):
    spec = with_resolution(load_scene("cornell_cd_view2"), RESOLUTION)
    cds = tuple(dataclasses.replace(cd, top_surface=top) for cd in spec.cds)
    return dataclasses.replace(spec, cds=cds)


def _forward_pixel(spec, light_point: np.ndarray, wavelength: float, order: int) -> np.ndarray | None:
    """The pixel where light from ``light_point`` diffracted into ``order`` reaches the camera
    (CD without a top), from the grating equation alone; None if no CD point does it."""
    cd = prediction.cd_geometry(spec)
    camera = spec.camera.model
    origin = -camera.world_to_camera[:3, :3].T @ camera.world_to_camera[:3, 3]
    e1, e2 = cd.frame[:, 0], cd.frame[:, 1]

    def residual(uv):
        p = cd.center + uv[0] * e1 + uv[1] * e2
        travel = (p - light_point) / np.linalg.norm(p - light_point)
        out = (origin - p) / np.linalg.norm(origin - p)
        x_hat = (p - cd.center) / np.linalg.norm(p - cd.center)
        y_hat = np.cross(cd.normal, x_hat)
        k_in = np.array([travel @ x_hat, travel @ y_hat])  # tangential k of the incident wave, over k0
        k_out = np.array([out @ x_hat, out @ y_hat])
        predicted_kx = order_kx(k_in[0], order, cd.period_um * 1000.0, wavelength)
        return [k_out[0] - predicted_kx, k_out[1] - k_in[1]]

    best = None
    for r in np.linspace(0.2, 0.95, 6) * cd.outer_radius:
        for a in np.radians(np.arange(0, 360, 30)):
            uv, info, ok, _ = fsolve(residual, [r * math.cos(a), r * math.sin(a)], full_output=True)
            radius = float(np.hypot(*uv))
            if ok == 1 and np.max(np.abs(info["fvec"])) < FORWARD_SOLVE_TOLERANCE and \
                    cd.inner_radius * 1.1 < radius < cd.outer_radius * 0.95:
                best = uv
                break
        if best is not None:
            break
    if best is None:
        return None
    return camera.project((cd.center + best[0] * e1 + best[1] * e2)[None])[0]


@pytest.mark.parametrize("order, wavelengths", [(-1, (450.0, 550.0, 650.0)), (2, (410.0, 440.0, 470.0))])
def test_forward_light_centre_is_lit_at_its_wavelength(order, wavelengths):
    """cornell_cd_view2's orders -1 (the whole range) and 2 (blue: longer waves miss the light)."""
    spec = _scene(top=False)
    centre = np.asarray(spec.light.center)
    checked = 0
    for wavelength in wavelengths:
        pixel = _forward_pixel(spec, centre, wavelength, order)
        if pixel is None:
            continue
        wavelengths, table = prediction.lit_table(spec, spec.camera.model, pixel[None], order)
        lit = wavelengths[table[0]]
        assert len(lit), f"order {order}, {wavelength} nm: the forward pixel {pixel} is not lit at all"
        assert lit.min() - STEP_NM <= wavelength <= lit.max() + STEP_NM
        checked += 1
    assert checked >= 2, "the forward model found too few pixels to check"


def test_forward_light_edge_ends_the_lit_wavelengths():
    """Light from the middle of the light's edge arrives at the edge of the pixel's lit set."""
    spec = _scene(top=False)
    centre, half = np.asarray(spec.light.center), np.asarray(spec.light.size) / 2
    checked = 0
    for dx, dz in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        edge = centre + np.array([dx * half[0], 0.0, dz * half[1]])
        for order in (-1, 2):
            for wavelength in (480.0, 560.0, 620.0):
                pixel = _forward_pixel(spec, edge, wavelength, order)
                if pixel is None:
                    continue
                wavelengths, table = prediction.lit_table(spec, spec.camera.model, pixel[None], order)
                lit = table[0]
                boundaries = wavelengths[:-1][lit[:-1] != lit[1:]] + STEP_NM / 2  # between a lit and an unlit sample
                if not len(boundaries):
                    continue
                assert np.min(np.abs(boundaries - wavelength)) <= EDGE_TOLERANCE_NM
                checked += 1
    assert checked >= 4


def test_top_refraction_follows_snell():
    spec = _scene(top=True)
    cd = prediction.cd_geometry(spec)
    camera = spec.camera.model
    pixels = camera.project((cd.center + 0.6 * cd.outer_radius * cd.frame[:, 0])[None])  # on the disc, off the hole
    origin, rays = prediction.pixel_rays(camera, pixels)
    n_top = 1.59
    points, ok = prediction.trace_to_grating(origin, rays, cd, n_top)
    assert ok[0]
    t = ((cd.center + cd.top_thickness_m * cd.normal - origin) @ cd.normal) / (rays[0] @ cd.normal)
    entry = origin + t * rays[0]
    inside = (points[0] - entry) / np.linalg.norm(points[0] - entry)
    sin_air = np.linalg.norm(np.cross(rays[0], cd.normal))
    sin_top = np.linalg.norm(np.cross(inside, cd.normal))
    assert abs(sin_air - n_top * sin_top) < SNELL_TOLERANCE
    # the refracted ray stays in the plane of incidence and goes on into the top
    assert abs(np.dot(np.cross(rays[0], cd.normal), inside)) < SNELL_TOLERANCE
    assert inside @ cd.normal < 0


def test_full_spectrum_pixels_have_lit_fraction_one():
    """Where an order delivers every wavelength of the camera's range, each channel's
    weighted lit fraction is 1 (a Lambertian light: no profile weight; the geometric weighting:
    the efficiency weighting is tested in test_prediction_efficiency.py)."""
    spec = _scene(top=True)
    # one ray per pixel: lit_nm and lit describe the same ray
    result = prediction.predict(spec, supersample=1, weighting="geometric")
    i = result.orders.index(-1)  # cornell_cd_view2's order -1 spans the whole range somewhere
    full = (result.lit_nm[i, 0] <= result.wavelengths_nm[0]) & (result.lit_nm[i, 1] >= result.wavelengths_nm[-1])
    assert full.sum() >= 5
    partial = np.isfinite(result.lit_nm[i, 0]) & ~full
    assert np.allclose(result.lit[i][:, full], 1.0, atol=1e-9)
    assert np.all(result.lit[i][:, partial].min(axis=0) < 1.0 - 1e-9)  # some channel misses part of its light
    assert np.allclose(result.weights.sum(axis=1), 1.0)


def test_band_moves_with_the_camera_like_the_image():
    """A camera turned about its centre sees the same rays: every band moves as the image
    does, so the lit sets at corresponding pixels agree."""
    from scipy.spatial.transform import Rotation

    spec = _scene(top=True)
    camera = spec.camera.model
    turn = Rotation.from_rotvec(np.radians([0.0, 0.5, 0.0])).as_matrix()
    turned = dataclasses.replace(camera, world_to_camera=np.block([[turn @ camera.world_to_camera[:3, :3],
                                                                    (turn @ camera.world_to_camera[:3, 3])[:, None]],
                                                                   [np.zeros((1, 3)), np.ones((1, 1))]]))
    cd = prediction.cd_geometry(spec)
    world = cd.center[None] + 0.5 * cd.outer_radius * np.stack([cd.frame[:, 0], cd.frame[:, 1], -cd.frame[:, 0]])
    # the same world directions through both cameras: pixels that see the same CD point
    for order in (-1, 2):
        _, a = prediction.lit_table(spec, camera, camera.project(world), order)
        _, b = prediction.lit_table(spec, turned, turned.project(world), order)
        assert np.array_equal(a, b)


def test_cd_out_of_view_is_a_user_error():
    spec = _scene()
    camera = spec.camera.model
    away = CameraModel(camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy, camera.dist,
                       np.diag([-1.0, 1.0, -1.0, 1.0]) @ camera.world_to_camera)  # turned half round
    with pytest.raises(UserInputError, match="does not see the CD"):
        prediction.predict(spec, away)


def test_scene_without_cd_is_a_user_error():
    spec = dataclasses.replace(_scene(), cds=())
    with pytest.raises(UserInputError, match="no CD"):
        prediction.predict(spec)

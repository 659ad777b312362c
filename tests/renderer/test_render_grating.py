"""Render-level check: a flat 1D grating lit by a small narrow-band source.

The spots of orders -1, 0, +1 must appear where the grating equation puts them, within
1 pixel. The prediction is computed here in numpy (n sin(theta_m) = n sin(theta_i) -
m lambda / Lambda, our order sign), independently of the plugin, as points on the grating;
to stay independent of the camera's pixel conventions, those points are rendered as tiny
emissive markers in a second image, and the two images' spot centroids are compared.
"""

import math

import numpy as np
import pytest
from scipy import ndimage
from scipy.optimize import brentq

import rcwa
from rcwa.table import build_table, settings_for

PERIOD_UM = 1.0
WAVELENGTH_NM = 550.0
CAMERA = np.array([0.0, 0.0, 1.0])
LIGHT = np.array([0.25, 0.0, 0.9])
LIGHT_RADIUS = 0.006
RESOLUTION = 192
FOV_DEG = 70.0
TOLERANCE_PIXELS = 1.0


def _predicted_spot(m: int) -> float:
    """x on the grating (z = 0, y = 0) where the order-m path from the camera hits the light."""
    def mismatch(x):
        p = np.array([x, 0.0, 0.0])
        to_cam = (CAMERA - p) / np.linalg.norm(CAMERA - p)
        to_light = (LIGHT - p) / np.linalg.norm(LIGHT - p)
        # Light's incident wave: k_t = -to_light_t; order m leaves with k_t - m lambda/Lambda.
        return (-to_light[0] - m * WAVELENGTH_NM / 1000.0 / PERIOD_UM) - to_cam[0]
    return brentq(mismatch, -0.9, 0.9)


def _scene(mi, bsdf, extra):
    # A symmetric 545-555 nm band: its centroid stays at 550 nm, and it smears the spots by
    # about 0.005 in direction cosine (well under a pixel here); narrower bands starve
    # the 4 sampled wavelengths of hits.
    narrow = {"type": "irregular", "wavelengths": "540, 545, 550, 555, 560", "values": "0, 0, 400, 0, 0"}
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 3},
        "sensor": {
            "type": "perspective", "fov": FOV_DEG,
            "to_world": mi.ScalarTransform4f().look_at(origin=CAMERA.tolist(), target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": RESOLUTION, "height": RESOLUTION, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": 256},
        },
        "grating": {"type": "rectangle", "bsdf": bsdf},
        "light": {"type": "sphere", "center": LIGHT.tolist(), "radius": LIGHT_RADIUS,
                  "emitter": {"type": "area", "radiance": narrow}},
        **extra,
    })


def _centroids(image: np.ndarray) -> list[tuple[float, float]]:
    lum = image.sum(axis=-1)
    # 8-connected: a noisy spot's pixels may touch only at corners.
    labels, count = ndimage.label(lum > 0.2 * lum.max(), structure=np.ones((3, 3)))
    found = ndimage.center_of_mass(lum, labels, range(1, count + 1))
    sizes = ndimage.sum(np.ones_like(lum), labels, range(1, count + 1))
    return [c for c, s in zip(found, sizes, strict=True) if s >= 1]


@pytest.mark.parametrize("mode", ["improved", "paper"])
def test_orders_appear_where_the_grating_equation_puts_them(mitsuba_variant, tmp_path, mode):
    import mitsuba as mi

    from renderer.bwdf import register

    register()
    grating = rcwa.Structure.from_dict({
        "period": [PERIOD_UM], "superstrate": "air", "substrate": {"n": 0.3, "k": 3.0},
        "layers": [{"thickness": 0.1, "material": "air", "shapes": [{"material": {"n": 0.3, "k": 3.0}, "x": [0.0, 0.5]}]}],
    })
    st = settings_for(grating, "draft", wavelengths="500:600:3", theta_step=2.0, phi_step=10.0, orders=21, keep=3)
    build_table(grating, st, tmp_path / "g.zarr", progress=False)
    bsdf = {"type": "bwdf", "filename": str(tmp_path / "g.zarr"), "mode": mode}
    image = np.array(mi.render(_scene(mi, bsdf, {}), seed=1))
    spots = sorted(_centroids(image), key=lambda c: c[1])

    markers = {f"marker{m}": {"type": "sphere", "center": [_predicted_spot(m), 0.0, 0.0], "radius": 0.003,
                              "emitter": {"type": "area", "radiance": 50.0}} for m in (-1, 0, 1)}
    reference = np.array(mi.render(_scene(mi, {"type": "diffuse", "reflectance": 0.0}, markers), seed=1))
    expected = sorted(_centroids(reference), key=lambda c: c[1])
    assert len(expected) == 3
    assert len(spots) == 3, f"found {len(spots)} spots"
    for got, want in zip(spots, expected, strict=True):
        assert math.dist(got, want) < TOLERANCE_PIXELS, (got, want)

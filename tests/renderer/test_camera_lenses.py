"""Every lens model renders through the projection calibration fits (renderer/camera.py, renderer/lens.py).

* The warp's sampling maps: every output pixel samples the ideal pinhole image where its own
  ray (CameraModel.normalized) lands, so projecting that ray back through the camera returns
  the pixel to WARP_PX (float32 maps of a ~1000 px image: 1e-4 px is their rounding).
* Rendered: tiny emissive spheres (as tests/renderer/test_camera.py) drawn through a wide
  fisheye (120 degrees across the diagonal), an omnidirectional and a rational camera land
  where CameraModel.project puts them, within RENDER_PX (rendered at 4 x the resolution, so that
  the blobs' centroids measure it; measured max 0.044 px fisheye, 0.044 omnidir, 0.067 rational).
* A field the pinhole intermediate cannot hold (a fisheye seeing 80 degrees off its axis at
  the corners) is refused with a clear error; a pincushion lens gets a denser intermediate.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import ndimage

from renderer.camera import MAX_HALF_FIELD_DEG, CameraModel, look_at
from workbench.core.errors import UserInputError

WARP_PX = 1e-3
RENDER_PX = 0.1          # the bar for a rendered target's points projected through each model
RADIUS_M = 0.012        # spheres 1-2 px across: a sub-pixel blob's centroid locks to the pixel grid (0.2-0.4 px at 4 mm)
POSE = look_at([0.2, -0.4, 1.4], [0, 0, 0], [0, 1, 0])
CAMERAS = {
    "fisheye": CameraModel(160, 120, 95.0, 95.0, 81.0, 58.5, (0.02, -0.01, 0.003, -0.001), POSE, "fisheye"),
    "omnidir": CameraModel(160, 120, 180.0, 180.0, 78.5, 61.0, (-0.1, 0.03, 0.001, -0.001), POSE, "omnidir", 1.1),
    "rational": CameraModel(160, 120, 150.0, 150.0, 80.5, 58.0, (0.25, 0.05, 0.001, -0.001, 0.0, 0.05, 0.0, 0.0),
                            POSE, "rational"),
}
POINTS = np.array([[0.0, 0.0, 0.0], [0.42, 0.28, 0.1], [-0.45, 0.3, -0.1], [0.4, -0.33, 0.15], [-0.43, -0.3, 0.0],
                   [0.05, 0.36, -0.2], [0.5, 0.0, 0.05]])


def _maps(cam: CameraModel):
    plan = cam.pinhole_plan()
    u, v = np.meshgrid(np.arange(cam.width, dtype=float), np.arange(cam.height, dtype=float))
    rays = cam.normalized(np.stack([u.ravel(), v.ravel()], 1))
    map_x = (rays[:, 0] * plan.focal + (plan.width - 1) / 2).astype(np.float32)
    map_y = (rays[:, 1] * plan.focal + (plan.height - 1) / 2).astype(np.float32)
    return plan, np.stack([u.ravel(), v.ravel()], 1), map_x, map_y


@pytest.mark.parametrize("name", list(CAMERAS))
def test_warp_samples_each_pixel_on_its_own_ray(name):
    cam = CAMERAS[name]
    plan, pixels, map_x, map_y = _maps(cam)
    rays = np.c_[(map_x - (plan.width - 1) / 2) / plan.focal, (map_y - (plan.height - 1) / 2) / plan.focal]
    origin = -cam.world_to_camera[:3, :3].T @ cam.world_to_camera[:3, 3]
    world = origin + np.c_[rays, np.ones(len(rays))] @ cam.world_to_camera[:3, :3]
    assert np.max(np.linalg.norm(cam.project(world) - pixels, axis=1)) < WARP_PX
    assert cam.half_field_deg() <= MAX_HALF_FIELD_DEG


def _centroids(image, expected):
    labels, count = ndimage.label(image > 0.01 * image.max())
    found = np.array(ndimage.center_of_mass(image, labels, range(1, count + 1)))[:, ::-1]
    return np.array([found[np.argmin(np.linalg.norm(found - e, axis=1))] for e in expected]), count


@pytest.mark.parametrize("name", list(CAMERAS))
def test_rendered_points_land_where_each_model_projects_them(mitsuba_variant, name):
    import mitsuba as mi

    small = CAMERAS[name]   # at 4 x the resolution: blobs 5-10 px across, whose centroids are not locked to pixels
    cam = dataclasses.replace(small, width=4 * small.width, height=4 * small.height, fx=4 * small.fx, fy=4 * small.fy,
                              cx=4 * small.cx + 1.5, cy=4 * small.cy + 1.5)
    expected = cam.project(POINTS)
    assert np.all((expected > 20) & (expected < [620, 460]))
    plan = cam.pinhole_plan()
    scene = {"type": "scene", "integrator": {"type": "direct"}, "sensor": plan.sensor_dict(mi, 64)}
    for i, p in enumerate(POINTS):
        scene[f"m{i}"] = {"type": "sphere", "center": p.tolist(), "radius": RADIUS_M,
                          "emitter": {"type": "area", "radiance": 10.0}}
    image = cam.warp(np.array(mi.render(mi.load_dict(scene), seed=0)), plan).sum(-1)
    got, count = _centroids(image, expected)
    assert count == len(POINTS)
    assert np.max(np.linalg.norm(got - expected, axis=1)) < RENDER_PX


def test_too_wide_a_field_is_refused_and_a_pincushion_gets_a_denser_intermediate():
    wide = CameraModel(160, 120, 40.0, 40.0, 79.5, 59.5, (0.0, 0.0, 0.0, 0.0), POSE, "fisheye")
    assert wide.half_field_deg() > MAX_HALF_FIELD_DEG
    with pytest.raises(UserInputError, match="degrees off its axis"):
        wide.pinhole_plan()
    pincushion = CAMERAS["rational"]
    assert pincushion.pinhole_plan().focal > 1.1 * pincushion.fx   # its edges are sampled finer than the centre (1.18)

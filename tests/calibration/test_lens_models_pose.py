"""Every lens model through the pose path (calibration/pose/inputs.py, pose_fit.py, pose_uncertainty.py,
fitted_scene.py, renderer/scene.py; issue 26, item 1: "everything that reads the camera file").

* intrinsics.json of a fisheye or omnidir calibration loads with its model, coefficients and xi;
  a wrong coefficient count is refused naming the field;
* the pose fit's projections (its Jacobian-carrying one and the coarse stage's fast one) are the
  camera's own projection for every model, to 1e-9 px, and the Jacobian's pose columns match
  central differences (so the fine fit's Gauss-Newton steps are right);
* the fitted scene's camera table reads back as the same camera (model, coefficients, xi), and the
  pose uncertainty's readout carries the model's own number of coefficients.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from calibration.pose.edge_fit import ChamferCost, Unknowns, project
from calibration.pose.inputs import load_intrinsics
from calibration.pose.scene_file import camera_table, fitted_scene_text
from calibration.pose.uncertainty import derived_std
from renderer.camera import CameraModel, look_at
from renderer.scene import load_scene, parse_scene
from workbench.core.errors import UserInputError

POSE = look_at([0.2, -0.4, 1.4], [0, 0, 0], [0, 1, 0])
CAMERAS = [
    CameraModel(320, 240, 190.0, 191.0, 161.0, 118.5, (0.02, -0.01, 0.003, -0.001), POSE, "fisheye"),
    CameraModel(320, 240, 360.0, 360.0, 158.5, 121.0, (-0.1, 0.03, 0.001, -0.001), POSE, "omnidir", 1.1),
    CameraModel(320, 240, 300.0, 300.0, 160.5, 118.0, (0.25, 0.05, 0.001, -0.001, 0.0, 0.05, 0.0, 0.0), POSE,
                "rational"),
]
POINTS = np.array([[0.0, 0.0, 0.0], [0.42, 0.28, 0.1], [-0.45, 0.3, -0.1], [0.4, -0.33, 0.15], [0.05, 0.36, -0.2]])
SAME_PX = 1e-9          # the same projection, evaluated two ways: round-off
JACOBIAN_REL = 1e-5     # analytic against central differences (step 1e-6): their truncation error


@pytest.mark.parametrize("camera", CAMERAS, ids=lambda c: c.model)
def test_pose_fit_projects_through_the_lens_model(camera):
    pixels, jac = project(camera, POINTS, with_jacobian=True)
    assert np.max(np.abs(pixels - camera.project(POINTS))) < SAME_PX
    unknowns = Unknowns(intrinsics=False)
    x0 = unknowns.vector(camera)
    cost = ChamferCost(None, POINTS, camera, x0, np.ones(len(x0)), intrinsics=False)  # type: ignore[arg-type]
    assert np.max(np.abs(cost.pixels(np.zeros(len(x0))) - pixels)) < SAME_PX
    h = 1e-6
    for k in range(6):
        step = np.eye(len(x0))[k] * h
        ahead = project(unknowns.camera(x0 + step, camera), POINTS)
        back = project(unknowns.camera(x0 - step, camera), POINTS)
        numeric = ((ahead - back) / (2 * h)).ravel()
        assert np.allclose(jac[:, k], numeric, rtol=JACOBIAN_REL, atol=JACOBIAN_REL * np.max(np.abs(numeric)))


def test_intrinsics_of_any_model_load_and_a_wrong_count_is_refused(tmp_path):
    path = tmp_path / "intrinsics.json"
    record = {"width": 320, "height": 240, "fx": 360.0, "fy": 360.0, "cx": 158.5, "cy": 121.0, "model": "omnidir",
              "xi": 1.1, "dist": [-0.1, 0.03, 0.001, -0.001]}
    path.write_text(json.dumps(record))
    loaded = load_intrinsics(path)
    assert loaded["model"] == "omnidir" and loaded["xi"] == 1.1 and loaded["dist"] == (-0.1, 0.03, 0.001, -0.001)
    path.write_text(json.dumps(dict(record, model="rational")))
    with pytest.raises(UserInputError, match="field 'dist'"):
        load_intrinsics(path)
    path.write_text(json.dumps(dict(record, model="pinhole", dist=[0.1, 0.0, 0.0, 0.0])))   # 4 pinhole terms: k3 = 0
    assert load_intrinsics(path)["dist"] == (0.1, 0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("camera", CAMERAS, ids=lambda c: c.model)
def test_the_fitted_scene_camera_reads_back_with_its_model(camera):
    spec = load_scene("cornell_cd")
    camera = dataclasses.replace(camera, world_to_camera=spec.camera.model.world_to_camera)   # a pose inside the box
    back = parse_scene(fitted_scene_text(spec, camera, 1.0), source="fitted_scene.toml", base_dir=None).camera.model
    assert (back.model, back.xi, back.dist) == (camera.model, camera.xi, camera.dist)
    assert np.max(np.abs(back.project(POINTS) - camera.project(POINTS))) < 1e-6
    std = derived_std(camera, Unknowns(intrinsics=False), np.eye(6) * 1e-8,
                      fixed_std={"fx": 1.0, "fy": 1.0, "cx": 0.5, "cy": 0.5, "dist": [0.01] * len(camera.dist)})
    assert std["dist"] == [0.01] * len(camera.dist)
    table = camera_table(camera, 1.0, "Nikon 5100 (NPL)", None)
    assert table.get("model", "pinhole") == camera.model
    with pytest.raises(ValueError, match="coefficients"):
        dataclasses.replace(camera, dist=(0.0,) * 5 if camera.model != "pinhole" else (0.0,) * 4)

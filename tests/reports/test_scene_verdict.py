"""The camera's uncertainty as the scene fit propagates it (reports.scene_fit.verdict.camera_effect).

A pose fit pins the camera's rotation and its principal point (or its centre) together far
better than either alone: a turn about the camera's y axis by delta moves a point at field
angle alpha by fx delta sec^2(alpha) pixels, a shift of cx moves every point alike, so under
a correlation of -1 with fx delta = sigma_cx their sum moves a point by fx delta tan^2(alpha),
under 0.03 of either alone for the CD's field angles (under 10 deg from the axis). The
propagated edge covariance must keep that (the joint ``covariance`` of
calibration.pose.uncertainty.derived_std), and reduce to the independent standard
deviations' when the covariance is diagonal.

The band edges and rim points are those of a forward-model photo of cornell_cd (the
scene's own camera, the file's period), as in tests/reports/test_scene_fit.py.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from renderer.fit_parameters import parse_fit_table
from renderer.scene import load_scene
from reports.scene_fit.model import EdgeModel, View, view_grids
from reports.scene_fit.verdict import camera_effect, moved_by_readout
from tests.reports.test_scene_fit import forward_model_photo

ROTATION_STD_DEG = 0.05
NAMES = ["rotation_x_deg", "rotation_y_deg", "rotation_z_deg", "center_x_m", "center_y_m", "center_z_m",
         "fx", "fy", "cx", "cy"]
# A diagonal covariance's principal directions are the parameters' own axes: the same moves as the
# independent standard deviations', so the same columns to round-off (measured 9e-17 of the largest variance).
SAME_COVARIANCE_RTOL = 1e-9
CANCELLED_SHARE = 0.05  # bound on sd(correlated) / sd(independent): the geometry gives <= 0.03 (module docstring), measured 0.011


@pytest.fixture(scope="module")
def model_and_edges():
    base = load_scene("cornell_cd")
    spec = dataclasses.replace(base, fit=parse_fit_table({"cd[0].structure.period": {}}, base.cds, base.light))
    camera = spec.camera.model
    view = View("prediction", camera, forward_model_photo(spec, 1.6, 0), view_grids(spec, camera), {})
    model = EdgeModel(spec, spec.fit, [view])
    values = spec.fit.nominal()
    return model, values, model.observed_edges(values)


def _covariance(camera, correlation: float, axes: str = "y") -> dict:
    """A joint covariance of the rotation about ``axes`` and cx alone, with ``correlation``
    between the rotation about y and cx."""
    sigma_cx = camera.fx * math.radians(ROTATION_STD_DEG)
    stds = np.zeros(len(NAMES))
    for axis in axes:
        stds[NAMES.index(f"rotation_{axis}_deg")] = ROTATION_STD_DEG
    stds[NAMES.index("cx")] = sigma_cx
    matrix = np.diag(stds**2)
    i, j = NAMES.index("rotation_y_deg"), NAMES.index("cx")
    matrix[i, j] = matrix[j, i] = correlation * stds[i] * stds[j]
    return {"parameters": NAMES, "matrix": matrix}


def _edge_covariance(model_and_edges, camera_std: dict) -> np.ndarray:
    model, values, observed = model_and_edges
    view = dataclasses.replace(model.views[0], camera_std=camera_std)
    effect = camera_effect(model.with_views([view]), values, observed)
    assert effect is not None
    return effect.covariance()


@pytest.mark.slow
def test_a_diagonal_covariance_propagates_as_the_independent_standard_deviations(model_and_edges) -> None:
    camera = model_and_edges[0].views[0].camera
    joint = _edge_covariance(model_and_edges, {"covariance": _covariance(camera, 0.0, "xyz")})
    independent = _edge_covariance(model_and_edges, {"rotation_deg": ROTATION_STD_DEG, "translation_m": 0.0,
                                                     "cx": camera.fx * math.radians(ROTATION_STD_DEG)})
    scale = float(np.max(np.diag(independent)))
    assert scale > 0.1  # a 0.05 deg turn moves the CD's edges by about 0.4 px
    assert np.max(np.abs(joint - independent)) < SAME_COVARIANCE_RTOL * scale


@pytest.mark.slow
def test_a_turn_and_a_principal_point_that_compensate_leave_the_edges_in_place(model_and_edges) -> None:
    camera = model_and_edges[0].views[0].camera
    correlated = np.sqrt(np.diag(_edge_covariance(model_and_edges, {"covariance": _covariance(camera, -1.0)})))
    independent = np.sqrt(np.diag(_edge_covariance(model_and_edges, {"covariance": _covariance(camera, 0.0)})))
    share = float(np.sqrt(np.mean(correlated**2)) / np.sqrt(np.mean(independent**2)))
    assert share < CANCELLED_SHARE, share


def test_a_centre_move_keeps_the_turn_and_moves_the_centre() -> None:
    """moved_by_readout's centre is the camera's centre in the world (-R^T t), moved by exactly
    the given amount, the turn applied about the camera's axes (readout's dR = R' R^T)."""
    camera = load_scene("cornell_cd").camera.model
    names = ["rotation_x_deg", "rotation_y_deg", "rotation_z_deg", "center_x_m", "center_y_m", "center_z_m"]
    delta = np.array([0.2, -0.1, 0.3, 0.004, -0.002, 0.001])
    moved = moved_by_readout(camera, names, delta)

    def centre(c):
        return -c.world_to_camera[:3, :3].T @ c.world_to_camera[:3, 3]

    np.testing.assert_allclose(centre(moved) - centre(camera), delta[3:], atol=1e-12)
    turn = moved.world_to_camera[:3, :3] @ camera.world_to_camera[:3, :3].T
    angle = np.degrees(math.acos(np.clip((np.trace(turn) - 1) / 2, -1, 1)))
    assert angle == pytest.approx(float(np.linalg.norm(delta[:3])), rel=1e-9)

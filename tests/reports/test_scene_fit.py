"""The scene fit recovers a period it did not start from (reports.scene_fit.fit, issue 25).

The "photo" is the forward model's own prediction for a CD whose track pitch is 3 % longer
than the scene file's (lit fractions as linear RGB over a dark disc, with Gaussian noise),
seen by the scene's camera: a converged reference with a known answer, no renderer needed.
The fit starts from the file's 1.6 um and must land on 1.648 um, to within 0.3 % (the
issue's bar on rendered photos). Not within 4 of its standard deviations, measured: the
model's edges move in steps as a (pixel, wavelength) pair's back-traced ray crosses the
light's rim, so at 1 sub-ray per pixel the cost is flat within about 0.002 um and the fit
stopped at 1.6500 um with a std of 0.0003 um from 1 % noise (on rendered photos the
bootstrap's std, 0.0035 um, is far above that granularity). The photo is
predicted at the fit's own resolution (FIT_SUPERSAMPLE): made with 2 x 2 sub-rays per pixel
it carries a resolution bias of +0.15 % (measured: 1.6504 um, std 0.0003 um) that its
noise does not cover, which is the accuracy-versus-time question of `workbench study fit`,
not this test's; the verdict
must be ``model`` and name the period. With the photo made at the file's period the
verdict must be ``consistent``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from renderer.fit_parameters import parse_fit_table
from renderer.scene import load_scene
from renderer.trace.prediction import cd_geometry, predict
from reports.compare.images import Photo
from reports.scene_fit.fit import FitSettings, fit_scene
from reports.scene_fit.model import FIT_SUPERSAMPLE, EdgeModel, View, view_grids
from reports.scene_fit.verdict import verdict

TRUE_PERIOD = 1.648  # 3 % longer than cornell_cd's 1.6 um
PERIOD_BAR = 0.003  # relative: the bar for a fitted period
NOISE = 0.01  # of the lit fraction (about 1 % of a band's brightness, a draft render's noise)


def forward_model_photo(spec, period: float, seed: int) -> Photo:
    camera = spec.camera.model
    geometry = dataclasses.replace(cd_geometry(spec), period_um=period)
    pred = predict(spec, camera, geometry=geometry, supersample=FIT_SUPERSAMPLE)
    rgb = pred.total().transpose(1, 2, 0) + 0.05 * pred.full(pred.on_cd)[..., None]  # the disc's dim background
    rgb = rgb + np.random.default_rng(seed).normal(0.0, NOISE, rgb.shape)
    return Photo(np.asarray(rgb, np.float32), np.zeros(rgb.shape[:2], bool), "prediction", "linear")


def _fit(period: float, seed: int):
    base = load_scene("cornell_cd")
    spec = dataclasses.replace(base, fit=parse_fit_table({"cd[0].structure.period": {}}, base.cds, base.light))
    camera = spec.camera.model
    view = View("prediction", camera, forward_model_photo(spec, period, seed), view_grids(spec, camera), {})
    model = EdgeModel(spec, spec.fit, [view])
    result = fit_scene(model, FitSettings(rounds=2))
    return result, verdict(result, spec.fit.labels(), ["cd[0].structure.period"], ["prediction"])


@pytest.mark.slow
def test_a_longer_period_is_found_and_named() -> None:
    result, judged = _fit(TRUE_PERIOD, 0)
    fitted, std = float(result.values[0]), float(result.std[0])
    assert abs(fitted / TRUE_PERIOD - 1) < PERIOD_BAR, (fitted, std)
    assert std < PERIOD_BAR * TRUE_PERIOD, std
    assert judged["verdict"] == "model", judged
    assert [p["name"] for p in judged["parameters"]] == ["cd[0].structure.period"]
    assert judged["residuals_after_px"]["median"] < judged["residuals_before_px"]["median"]


@pytest.mark.slow
def test_the_file_period_is_consistent() -> None:
    result, judged = _fit(1.6, 1)
    assert judged["verdict"] == "consistent", judged
    assert abs(float(result.values[0]) - 1.6) < 3 * float(result.std[0])


def _fit_a_structure_field(name: str, field: str, truth: float):
    """A forward-model photo with the structure field ``field`` (scene_fit_efficiency.field_name) at
    ``truth``, 1 % noise, fitted with ``name`` free in [fit]: the fit's result."""
    from reports.scene_fit.structure_tables import StructureEfficiencies

    base = load_scene("cornell_cd")
    spec = dataclasses.replace(base, fit=parse_fit_table({name: {}}, base.cds, base.light))
    tables = StructureEfficiencies(spec, list(spec.fit.free))
    pred = predict(spec, spec.camera.model, supersample=FIT_SUPERSAMPLE,
                   efficiency=tables.at({field: truth}))  # type: ignore[arg-type]
    rgb = pred.total().transpose(1, 2, 0) + 0.05 * pred.full(pred.on_cd)[..., None]
    rgb = rgb + np.random.default_rng(2).normal(0.0, NOISE, rgb.shape)
    photo = Photo(np.asarray(rgb, np.float32), np.zeros(rgb.shape[:2], bool), "prediction", "linear")
    view = View("prediction", spec.camera.model, photo, view_grids(spec, spec.camera.model), {})
    return fit_scene(EdgeModel(spec, spec.fit, [view]), FitSettings())


@pytest.mark.slow
def test_a_deeper_groove_is_found_through_the_efficiencies() -> None:
    """The groove depth moves no direction, only the orders' efficiencies (reports.scene_fit.structure_tables:
    tables at 7 depths, blended linearly): a photo predicted at 0.125 um (the file's 0.11 um, +14 %)
    with 1 % noise must be fitted within 0.003 um (about a tenth of the node spacing, 0.011 um;
    measured 0.1247 um, std 0.0004)."""
    result = _fit_a_structure_field("cd[0].structure.layers[0].thickness", "layers[0].thickness", 0.125)
    assert abs(float(result.values[0]) - 0.125) < 0.003, (result.values, result.std)


@pytest.mark.slow
def test_a_wider_groove_is_found_through_the_efficiencies() -> None:
    """The groove's width, like its depth, moves no direction, only the orders' efficiencies
    (tables at 7 widths across +-30 % of 0.6 um). The band edges tell it far less well than
    the depth (measured: 0.634 +- 0.029 um for a photo predicted at 0.66 um with 1 % noise):
    the fit must move from the file's 0.6 um toward the truth, state a std under
    ``WIDTH_STD_BAR_UM`` and hold the truth within ``WIDTH_SIGMAS`` of it (seeded noise: only
    round-off moves the draw)."""
    result = _fit_a_structure_field("cd[0].structure.layers[0].shapes[0].width", "layers[0].shapes[0].width", 0.66)
    error = abs(float(result.values[0]) - 0.66)
    assert error < 0.06 and float(result.std[0]) < WIDTH_STD_BAR_UM, (result.values, result.std)
    assert error < WIDTH_SIGMAS * float(result.std[0]), (result.values, result.std)


WIDTH_STD_BAR_UM = 0.05  # measured 0.029 um: under this the edges say something about the width (the bounds span 0.36)
WIDTH_SIGMAS = 3.0  # measured 0.89
RIM_NOISE_PX = 0.5  # per rim point, about what the photos' rim search leaves (0.55-0.8 px measured)
RIM_TILT_BAR_DEG = 0.3  # 96 points at 0.5 px give a tilt std near 0.1 deg (0.5 px per deg at the rim)


def _rim_start(tilt_deg: float, seed: int) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """rim_start on rim points alone: those of cornell_cd's CD tilted ``tilt_deg`` toward e2, noisy."""
    from reports.scene_fit.apply import apply_values
    from reports.scene_fit.fit import rim_start

    base = load_scene("cornell_cd")
    table = parse_fit_table({"cd[0].normal": {}, "cd[0].structure.period": {}}, base.cds, base.light)
    spec = dataclasses.replace(base, fit=table)
    labels = table.labels()
    truth = table.nominal()
    truth[labels.index("cd[0].normal:tilt_e2")] = tilt_deg
    camera = spec.camera.model
    rim = camera.project(cd_geometry(apply_values(spec, table, truth).spec).rim_points(count=96))
    rim = rim + np.random.default_rng(seed).normal(0.0, RIM_NOISE_PX, rim.shape)
    blank = Photo(np.zeros((camera.height, camera.width, 3), np.float32), np.zeros((camera.height, camera.width), bool),
                  "rim only", "linear")
    model = EdgeModel(spec, table, [View("rim only", camera, blank, (), {}, rim_points=rim)])
    return rim_start(model, table.nominal(), *table.bounds()), truth, labels


def test_rim_start_finds_a_tilt_the_band_edges_would_mispair() -> None:
    start, truth, labels = _rim_start(2.0, 0)
    tilt = [labels.index("cd[0].normal:tilt_e1"), labels.index("cd[0].normal:tilt_e2")]
    assert np.all(np.abs(start[tilt] - truth[tilt]) < RIM_TILT_BAR_DEG), start
    assert start[labels.index("cd[0].structure.period:value")] == 1.6  # the rim says nothing of the period


def test_rim_start_keeps_the_file_values_where_the_rim_agrees_within_its_noise() -> None:
    """The rim-only shift's chi-square (2 degrees of freedom, under the rim's noise plus its
    systematic RIM_SYSTEMATIC) is judged at RIM_START_ALPHA = 1e-3: under the file's CD a noise
    draw moves the start less than once in 1000. Seeded draws (a fixed NumPy stream: only
    round-off moves them); measured statistics 0.23, 0.20 and 0.68 against the bound's 13.8,
    while the 2 deg tilt above gives 22.8."""
    for seed in (1, 2, 3):
        start, truth, _ = _rim_start(0.0, seed)
        np.testing.assert_array_equal(start, truth)


CAMERA_TURN_DEG = 0.3  # the photo's true camera, turned about its vertical axis from the calibrated one


def _fit_with_a_turned_camera(rotation_std_deg: float):
    """A photo predicted at the file's period through a camera turned CAMERA_TURN_DEG (2.4 px at
    cornell_cd's 456 px focal length), fitted (the period free) with the unturned camera and a
    calibration whose rotation std is ``rotation_std_deg``."""
    from reports.fringes.prediction_band import moved_camera
    from reports.scene_fit.verdict import camera_effect

    base = load_scene("cornell_cd")
    spec = dataclasses.replace(base, fit=parse_fit_table({"cd[0].structure.period": {}}, base.cds, base.light))
    calibrated = spec.camera.model
    true = moved_camera(calibrated, [0.0] * 4, np.array([0.0, CAMERA_TURN_DEG, 0.0]), np.zeros(3))
    photo = forward_model_photo(dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, model=true)), 1.6, 3)
    view = View("prediction", calibrated, photo, view_grids(spec, calibrated), {"rotation_deg": rotation_std_deg})
    model = EdgeModel(spec, spec.fit, [view])
    result = fit_scene(model, FitSettings(rounds=2), lambda x, observed: camera_effect(model, x, observed))
    return verdict(result, spec.fit.labels(), ["cd[0].structure.period"], ["prediction"])


@pytest.mark.slow
def test_a_camera_turned_within_a_weak_calibration_is_called_camera() -> None:
    """Issue 25's ``camera`` verdict: the calibration pins the pose to 0.3 deg only (one std),
    and the camera turned by that much explains the band edges: the camera-only fit brings them
    to the unperturbed level, naming rotation_deg (moved about one std; bar 2, its prior's 2
    sigma), while the scene file's edges are off by more (median above REMOVED_MEDIAN_PX)."""
    from reports.scene_fit.verdict import REMOVED_MEDIAN_PX

    judged = _fit_with_a_turned_camera(CAMERA_TURN_DEG)
    assert judged["residuals_before_px"]["median"] > REMOVED_MEDIAN_PX, judged["residuals_before_px"]
    assert judged["verdict"] == "camera", judged
    moved = judged["camera_fit"]["moved_std"]
    assert list(moved)[0] == "rotation_deg" and 0.5 < moved["rotation_deg"] < 2.0, moved


@pytest.mark.slow
def test_the_same_turn_under_a_calibration_that_pins_the_pose_is_not_the_camera() -> None:
    """With the rotation's std at 0.01 deg the 0.3 deg turn is 30 std: the camera cannot explain
    it, nor can the period; the verdict is neither ``camera`` nor ``consistent``."""
    judged = _fit_with_a_turned_camera(0.01)
    assert judged["verdict"] == "unexplained", judged

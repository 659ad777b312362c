"""``workbench study calibrate`` (calibration/study.py): error against time of the pose fit.

Slow: a tiny grid on the suite's shared seed-0 draft dataset (tests/conftest.py), one
photo (view0.dng), two fits: the default settings at full resolution and the same at a
quarter of it, plus the response's knot study with one knot count. Asserted: the output
files and their layout, the full-resolution fit within issue 14's bars, and the
quarter-resolution fit cheaper and less accurate. Fast: bad input before any fit.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from calibration.pose.study import ERRORS, CalibrateStudyConfig, run_calibrate_study, scaled_camera
from tests import calibration_bounds as bounds
from tests.conftest import synthetic_dataset
from workbench.core.errors import UserInputError

SEED = 0  # the dataset test_pose.py and test_dataset.py calibrate
# At full resolution (measured on seed 0, view0: 0.064 deg, 0.29 mm, FOV 0.016 deg (the boards'), principal point
# 0.2 %, exposure 0.03 %) within the bounds over render realisations (tests/calibration_bounds.py); issue 14's
# own bars (0.1 deg, 1 mm, ...) are missed by 1 realisation in 6 and are judged in benchmarks/bench_calibration.py.
BARS = {"rotation_deg": bounds.ROTATION_DEG, "centre_mm": bounds.CENTRE_MM, "fov_deg": bounds.FOV_DEG,
        "principal_point_pct": bounds.PRINCIPAL_POINT_PCT, "exposure_pct": bounds.EXPOSURE_PCT}
# A quarter of the resolution (160 x 120) puts each edge 4 full-resolution pixels wide:
# measured 2.9 mm and 0.2 deg against 0.29 mm and 0.064 deg, in an eighth of the time.
# Asserted loosely: the camera centre at least twice as far off, in less time.
QUARTER_CENTRE_FACTOR = 2.0
RESPONSE_RMS_PCT = 1.0  # issue 14's bar for the response curve (the parametric fit: 0.13 % with 3 knots)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    dataset = synthetic_dataset(tmp_path_factory, SEED)
    out = tmp_path_factory.mktemp("study_calibrate")
    cfg = CalibrateStudyConfig(fine=((4, (6.0, 4.0, 3.0, 2.5)),), scales=(1.0, 0.25), render_spp=(16,), knots=(3,),
                               photos=("view0.dng",))
    return out, run_calibrate_study(dataset, "cornell_cd", out, cfg, progress=False)


@pytest.mark.heavy  # the study's renders and fits: 1.5 min on 2 cores; `make bench` runs the study itself
def test_outputs_layout(study) -> None:
    out, data = study
    for name in ("study_calibrate.json", "calibrate_settings.csv", "calibrate_photos.csv", "response_knots.csv",
                 "study_calibrate.png", "study_calibrate.svg"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert json.loads((out / "study_calibrate.json").read_text()) == json.loads(json.dumps(data))
    assert not list(out.glob(".*.tmp*"))  # atomic writes leave no temporary files
    assert data["format"] == "workbench-study-calibrate" and data["photos"] == ["view0.dng"]
    assert {"mitsuba", "opencv", "workbench"} <= set(data["versions"]) and data["timings"]["total_s"] > 0
    assert data["config"]["scales"] == [1.0, 0.25] and data["config"]["base"]["render_spp"] == 16
    factors = [r["factor"] for r in data["error_vs_time"]]
    assert factors == ["fine", "scale", "scale", "render_spp"]  # one factor at a time; the base under each
    with open(out / "calibrate_settings.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4 and set(ERRORS) | {"seconds", "scale", "render_spp", "fine_rounds"} <= set(rows[0])
    assert all(np.isfinite(r[k]) for r in data["error_vs_time"] for k in ERRORS)


@pytest.mark.heavy
def test_full_resolution_meets_the_bars_and_a_quarter_costs_accuracy(study) -> None:
    _, data = study
    full, quarter = ([r for r in data["error_vs_time"] if r["factor"] == "scale" and r["scale"] == s][0] for s in (1.0, 0.25))
    for key, bar in BARS.items():
        assert full[key] < bar, (key, full)
    assert quarter["centre_mm"] > QUARTER_CENTRE_FACTOR * full["centre_mm"], (quarter, full)
    (knots,) = data["response_knots"]
    assert knots["knots"] == 3 and knots["response_rms_pct"] < RESPONSE_RMS_PCT


def test_scaled_camera_keeps_pixel_centres() -> None:
    """Downscaling by s maps pixel x to (x + 1/2) s - 1/2 (OpenCV's centres at integers):
    a point projects to the same place in the scaled image to rounding, and scaling back is exact."""
    from renderer.camera import CameraModel

    camera = CameraModel(width=640, height=480, fx=600.0, fy=601.0, cx=321.3, cy=238.7, dist=(-0.08, 0.02, 0, 0, 0),
                         world_to_camera=np.eye(4))
    points = np.array([[0.1, -0.05, 1.0], [-0.3, 0.2, 2.0]])
    small = scaled_camera(camera, 0.25)
    assert (small.width, small.height) == (160, 120)
    np.testing.assert_allclose(small.project(points), (camera.project(points) + 0.5) * 0.25 - 0.5, atol=1e-9)
    back = scaled_camera(small, 4.0)
    assert (back.fx, back.fy, back.cx, back.cy) == pytest.approx((camera.fx, camera.fy, camera.cx, camera.cy), rel=1e-14)


def _dataset(root: Path, truth: dict | None = None) -> Path:
    from PIL import Image

    (root / "photos").mkdir(parents=True)
    Image.fromarray(np.tile(np.linspace(0, 255, 64, dtype=np.uint8), (48, 1))).save(root / "photos" / "view0.png")
    if truth is not None:
        (root / "truth.json").write_text(json.dumps(truth))
    return root


def test_dataset_without_truth_is_refused(tmp_path: Path) -> None:
    dataset = _dataset(tmp_path / "real")
    with pytest.raises(UserInputError, match="workbench synth") as info:
        run_calibrate_study(dataset, "cornell_cd", tmp_path / "out", progress=False)
    assert info.value.file == str(dataset / "truth.json")
    assert not (tmp_path / "out").exists()


def test_truth_of_something_else_is_refused(tmp_path: Path) -> None:
    dataset = _dataset(tmp_path / "other", {"format": "someone-elses"})
    with pytest.raises(UserInputError) as info:
        run_calibrate_study(dataset, "cornell_cd", tmp_path / "out", progress=False)
    assert info.value.field == "format" and not (tmp_path / "out").exists()


def test_scale_that_gives_no_whole_pixels_is_refused(tmp_path: Path) -> None:
    truth = {"format": "workbench-synthetic-dataset", "camera": {"world_to_camera": {"view0.png": np.eye(4).tolist()}},
             "exposure_time_s": {}, "sensor": {}, "light_power_scale": 1.0}
    dataset = _dataset(tmp_path / "ds", truth)
    with pytest.raises(UserInputError, match="whole pixels") as info:
        run_calibrate_study(dataset, "cornell_cd", tmp_path / "out", CalibrateStudyConfig(scales=(1.0, 0.3)),
                            progress=False)
    assert info.value.field == "scales" and not (tmp_path / "out").exists()

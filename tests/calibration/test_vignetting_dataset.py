"""Issue 26 item 6 end to end: a synthetic lens's vignetting through synth, calibrate DATASET, render and report.

`workbench synth cornell_cd --seed 0 --vignetting 3.8,4,4.4` (the cos^p law per channel,
corners 30-36 % darker) is calibrated from a copy without its truth; the fitted falloff at
the image's corners is checked against the truth's (datasets_synthetic.sensor at the true
camera), the exposure on the lens's axis against the sensor model, and the fitted scene's
render is reported against the photo: the report multiplies the render by the falloff, so
the walls' photometric scale is 1 and their means agree at the calibrated exposure. The
seed-0 dataset without vignetting (shared with test_pose and test_dataset) must come out
with the stage fitted and not applied, leaving its numbers as they were.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from calibration.intrinsics.vignetting import CHANNELS
from datasets_synthetic.sensor import SensorModel
from renderer.camera import CameraModel
from tests.calibration.test_dataset import PHOTOMETRIC, expected_scale
from tests.calibration.test_pose import calibrated_dataset
from tests.conftest import synthetic_dataset
from workbench.cli import main

POWERS = (3.8, 4.0, 4.4)
CORNER_BAR = 0.01        # issue 26: the falloff within 1 % of the truth at the corners; over 4 render realisations
                         # (synth's render_seed 0-3) the 48 corner errors lay in -0.34..+0.48 %, SD 0.2 %: 5 SD
SCALE_AFTER = 0.02       # the report's walls scale, render x falloff against the photo: 1 within the 16-spp render's
                         # noise and the calibration's (measured 1.0009 at 64 spp; without the falloff it is 0.86)


@pytest.fixture(scope="module")
def vignetted(tmp_path_factory) -> tuple[Path, Path, dict, dict]:
    dataset = synthetic_dataset(tmp_path_factory, 0, vignetting=POWERS)
    return (dataset, *calibrated_dataset(tmp_path_factory, dataset))


def _true_corners(truth: dict) -> dict[str, np.ndarray]:
    c = truth["camera"]
    camera = CameraModel(c["width"], c["height"], c["fx"], c["fy"], c["cx"], c["cy"], tuple(c["dist"]))
    falloff = SensorModel(vignetting_power=tuple(truth["sensor"]["vignetting_power"])).relative_illumination(camera)
    rows, cols = [0, 0, c["height"] - 1, c["height"] - 1], [0, c["width"] - 1, 0, c["width"] - 1]
    return {ch: falloff[rows, cols, k] for k, ch in enumerate(CHANNELS)}


@pytest.mark.heavy  # a dataset of its own (synth + calibrate: 3.5 min on 2 cores); the fit: test_vignetting.py
def test_the_lens_falloff_is_recovered_at_the_corners(vignetted) -> None:
    _, _, result, truth = vignetted
    record = result["vignetting"]
    assert record["applied"], record["why"]
    assert tuple(truth["sensor"]["vignetting_power"]) == POWERS
    for ch, expected in _true_corners(truth).items():
        error = np.asarray(record["corners"][ch]) - expected
        assert np.all(np.abs(error) < CORNER_BAR), (ch, error)
        assert np.all(expected < 0.72)  # the truth is a real falloff (30-36 %), not a trivially passed one


@pytest.mark.heavy  # a dataset of its own (synth + calibrate: 3.5 min on 2 cores); the fit: test_vignetting.py
@pytest.mark.parametrize("photo", ["view0.dng", "view1.dng"])
def test_the_exposure_is_the_one_on_the_lens_axis(vignetted, photo: str) -> None:
    """With the falloff applied the scale is photo / (V render): the issue-14 bar of 1 % holds
    as on a lens without vignetting (the pose's scale alone, photo / render, is 10 % low)."""
    _, _, result, truth = vignetted
    assert result["exposure_scale"][photo] == pytest.approx(expected_scale(truth, photo), rel=PHOTOMETRIC)
    before = result["vignetting"]["exposure_scale_before"][photo]
    assert before < 0.95 * expected_scale(truth, photo)
    assert result["std"]["exposure_scale"][photo] < 0.01 * result["exposure_scale"][photo]


@pytest.mark.heavy  # a dataset of its own (synth + calibrate: 3.5 min on 2 cores); the fit: test_vignetting.py
def test_the_report_compares_the_photo_with_the_render_through_the_lens(vignetted, tmp_path) -> None:
    dataset, out, _, _ = vignetted
    exr = tmp_path / "render.exr"
    assert main(["render", str(out / "fitted_scene.toml"), "--out", str(exr), "--spp", "16", "--quiet"]) == 0
    assert main(["report", "--photo", str(dataset / "photos" / "view0.dng"), "--render", str(exr), "--calibration",
                 str(out / "calibration.json"), "--scene", "cornell_cd", "--out", str(tmp_path / "report")]) == 0
    report = json.loads((tmp_path / "report" / "report.json").read_text())
    assert report["photometric_scale"]["vignetting"]["applied"]
    assert report["photometric_scale"]["render_to_photo"] == pytest.approx(1.0, abs=SCALE_AFTER)
    walls = {name: row for name, row in report["region_test"]["regions"].items() if name.startswith("wall") and "z" in row}
    assert walls and all(row["consistent"] for row in walls.values()), walls
    page = (tmp_path / "report" / "report.html").read_text()
    assert "lens vignetting" in page and "a ray lands within" in page  # the lens's rows of the summary


@pytest.mark.slow
def test_a_lens_without_vignetting_keeps_its_numbers(tmp_path_factory) -> None:
    _, result, _ = calibrated_dataset(tmp_path_factory)
    record = result["vignetting"]
    assert not record["applied"], record["why"]
    assert "exposure_scale_before" not in record
    assert all(abs(1 - v) < 0.01 for values in record["corners"].values() for v in values)

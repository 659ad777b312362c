"""``workbench calibrate DATASET`` (calibration/dataset.py) and its command line.

Slow: the draft dataset of `workbench synth cornell_cd --seed 0`, calibrated from a copy
that holds only photos/, brackets/ and calibration/ (test_pose.calibrated_dataset, shared
with test_pose.py within a session). Asserted against truth.json:
* calibration.json's layout: the camera, world_to_camera for every photo by file name
  (truth.json's convention), std for each estimate, the response in truth.json's form;
* the photometric scale, exposure x light power, within 1 % of what the sensor model
  makes of the truth (light_power_scale x exposure time x electrons per unit x gain /
  (white - black): the photo's normalised raw value per unit of the scene file's render);
  and the same per second of exposure for every photo;
* the response curve within 1 % RMS over values 0.05-0.95;
* the run under two minutes on this machine (issue 14);
* fitted_scene.toml renders, and its render agrees with the photo in brightness.
Fast: a dataset without photos, a missing folder, `calibrate DATASET` routed to the
``dataset`` step, and user errors ending in exit status 2 with an error line.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from calibration.dataset import calibrate_dataset, dataset_files
from tests.calibration.test_pose import calibrated_dataset
from workbench.cli_calibrate_pose import route_dataset
from workbench.core.errors import UserInputError

PHOTOMETRIC = 0.01          # issue 14: exposure x light power within 1 %
PER_SECOND_SPREAD = 0.005   # the per-second scale of two photos of one scene: measured 0.002 % apart
RESPONSE_RMS = 0.01         # issue 14: response curve RMS < 1 % over values 0.05-0.95
DATASET_SECONDS = 120.0     # issue 14: `calibrate DATASET` on the draft dataset in under 2 minutes here
RENDER_BRIGHTNESS = 0.05    # an 80 x 60, 64 spp render of the fitted scene against the photo averaged to 80 x 60:
                            # the walls' mean agrees to the render's noise and the smaller image's edge pixels


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    return calibrated_dataset(tmp_path_factory)


@pytest.mark.slow
def test_calibration_json_layout(calibrated) -> None:
    out, result, truth = calibrated
    camera = result["camera"]
    assert {"width", "height", "fx", "fy", "cx", "cy", "dist", "world_to_camera"} <= set(camera)
    assert (camera["width"], camera["height"]) == (truth["camera"]["width"], truth["camera"]["height"])
    photos = {name for name in truth["camera"]["world_to_camera"] if name.startswith("view")}
    assert set(camera["world_to_camera"]) == photos
    for matrix in camera["world_to_camera"].values():
        T = np.asarray(matrix)
        assert T.shape == (4, 4) and np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9)
    std = result["std"]
    assert {"fx", "fy", "cx", "cy", "dist", "poses", "exposure_scale"} <= set(std)
    assert all(np.isfinite(std["poses"][name]["rotation_total_deg"]) for name in photos)
    assert result["light_power_scale"] == 1.0 and set(result["exposure_scale"]) == photos
    assert len(result["response"]["points"]) > 10
    assert {p.name for p in out.iterdir()} >= {"calibration.json", "fitted_scene.toml", "scenes", "intrinsics.json",
                                               "response.json"}
    assert "truth" not in json.dumps(result["files"])  # it read the three folders only


def expected_scale(truth: dict, photo: str) -> float:
    """The synthetic photo's normalised raw value per unit of the scene file's render (datasets_synthetic.sensor)."""
    sensor = truth["sensor"]
    return (truth["light_power_scale"] * truth["exposure_time_s"][photo] * sensor["electrons_per_unit"] * sensor["gain"]
            / (sensor["white_level"] - sensor["black_level"]))


@pytest.mark.slow
@pytest.mark.parametrize("photo", ["view0.dng", "view1.dng"])
def test_exposure_times_light_power_against_truth(calibrated, photo: str) -> None:
    _, result, truth = calibrated
    assert result["exposure_scale"][photo] == pytest.approx(expected_scale(truth, photo), rel=PHOTOMETRIC)
    assert result["exposure_time_s"][photo] == pytest.approx(truth["exposure_time_s"][photo], rel=1e-9)


@pytest.mark.slow
def test_per_second_scale_is_one_for_the_scene(calibrated) -> None:
    _, result, _ = calibrated
    values = list(result["exposure_scale_per_second"].values())
    assert max(values) / min(values) - 1 < PER_SECOND_SPREAD


@pytest.mark.slow
def test_response_against_truth(calibrated) -> None:
    from calibration.response import response_rms

    _, result, truth = calibrated
    assert response_rms(result["response"]["points"], truth["response"]["points"]) < RESPONSE_RMS


@pytest.mark.slow
def test_runs_in_under_two_minutes(calibrated) -> None:
    _, result, _ = calibrated
    assert result["timings"]["total_s"] < DATASET_SECONDS


@pytest.mark.slow
def test_fitted_scene_renders_like_the_photo(calibrated, tmp_path: Path) -> None:
    from calibration.photo import read_photo
    from workbench.cli import main

    out, result, truth = calibrated
    exr = tmp_path / "fitted.exr"
    assert main(["render", str(out / "fitted_scene.toml"), "--out", str(exr), "--spp", "64", "--resolution", "80x60",
                 "--quiet"]) == 0
    import mitsuba as mi  # the render set its variant

    render = np.array(mi.Bitmap(str(exr)))[..., :3].mean(axis=2)
    photo_path = Path(result["files"]["photos"][0])
    photo = cv2.resize(read_photo(photo_path).grey, (80, 60), interpolation=cv2.INTER_AREA)
    assert render.shape == photo.shape
    walls = photo < 0.95 * photo.max()  # leave out what the photo clipped
    assert render[walls].mean() == pytest.approx(photo[walls].mean(), rel=RENDER_BRIGHTNESS)


def test_dataset_without_photos_names_the_folder(tmp_path: Path) -> None:
    (tmp_path / "photos").mkdir()
    (tmp_path / "photos" / "notes.txt").write_text("no photos here")
    with pytest.raises(UserInputError, match="no photos") as info:
        dataset_files(tmp_path)
    assert info.value.file == str(tmp_path / "photos")


def test_missing_dataset_folder_is_refused(tmp_path: Path) -> None:
    with pytest.raises(UserInputError, match="no such dataset folder"):
        calibrate_dataset(tmp_path / "absent", "cornell_cd", tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


def test_calibrate_dataset_is_routed_to_the_dataset_step() -> None:
    steps = ("intrinsics", "response", "pose", "dataset")
    assert route_dataset(["calibrate", "/data/ds", "--scene", "s"], steps) == ["calibrate", "dataset", "/data/ds",
                                                                              "--scene", "s"]
    assert route_dataset(["--cache", "c", "calibrate", "ds"], steps) == ["--cache", "c", "calibrate", "dataset", "ds"]
    for unchanged in (["calibrate", "pose", "p.dng"], ["calibrate", "--help"], ["render", "scene.toml"]):
        assert route_dataset(unchanged, steps) == unchanged


@pytest.mark.parametrize("argv", [
    ["calibrate", "dataset", "{tmp}/absent", "--scene", "cornell_cd", "--out", "{tmp}/out"],
    ["calibrate", "pose", "{tmp}/absent.dng", "--scene", "cornell_cd", "--out", "{tmp}/out"],
])
def test_command_line_errors_exit_2(tmp_path: Path, capsys, argv: list[str]) -> None:
    from workbench.cli import main

    assert main([a.format(tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "absent" in err and "Traceback" not in err

"""``workbench report`` end to end on a real synthetic pair (issue 15's bars).

The photo is a raw file of a synthetic dataset (``workbench synth``, shared per session by
tests/conftest.py); the render is made here with the dataset's truth camera (renderer.rerender,
the path synth itself renders through, at the photo's 64 spp, another seed), and the
calibration is the dataset's truth.json. So the only differences between photo and render
are noise (Monte Carlo, shot and read noise, the Bayer mosaic): the band edges must agree
to issue 15's bars, and the grating-equation prediction must agree with both.
"""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from calibration.calibration_file import read_camera
from tests import realisation_bounds
from tests.conftest import synthetic_dataset
from workbench.cli import main

SCENE = "cornell_cd"  # its CD, propped toward the camera, shows first orders on a quarter of its pixels; the seed-0
# dataset is shared with the calibration tests (tests/calibration/test_pose.py)
SEED = 0
PHOTO = "ev+0.dng"  # view0 as exposed for the room: the CD's first orders (30-60x the walls) clip in it
BRACKET = ("ev-1.dng", "ev-2.dng", "ev-4.dng", "ev-6.dng", "ev+1.dng")  # the darker frames fill them (the brighter
# one is left out); reports.compare.exposure_merge
KNOWN_ERROR_PHOTO = "ev-2.dng"  # fewer clipped bands: the known-error pairs need both images' edges, clipped or not
RENDER_SPP = 64  # the photo's own
RENDER_SEED = 901  # not the photo's
# Bounds over render realisations (tests/realisation_bounds.py): issue 15's bars (median 0.5 px, p95 1.5 px, the
# prediction within 0.5 px of both, a known camera error to 0.5 px) pass or fail one realisation by the luck of the
# draw (the p95 bar failed 1 of 12) and are judged in benchmarks/bench_realisations.py.
MEDIAN_BAR_PX = realisation_bounds.PAIR_MEDIAN_PX
P95_BAR_PX = realisation_bounds.PAIR_P95_PX
PREDICTION_RENDER_PX = realisation_bounds.PREDICTION_RENDER_MEDIAN_PX
PREDICTION_PHOTO_PX = realisation_bounds.PREDICTION_PHOTO_MEDIAN_PX
MIN_EDGES = 8  # band edges of quality ok in both images: fewer would make the p95 a guess
SIZE_BYTES = 15e6  # issue 15: the report folder under 15 MB
KNOWN_ERROR_SPP = 32  # the wrong camera's render: the photo's noise dominates the pairs' anyway (64 spp measured 0.31 px)
MIN_KNOWN_EDGES = 20
MIN_PREDICTION_EDGES = 5  # reports.report's own threshold for a prediction-photo median worth stating


def _spec(camera):
    from renderer.render import with_resolution
    from renderer.scene import load_scene

    spec = with_resolution(load_scene(SCENE), (camera.width, camera.height))
    return dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, model=camera))


def _render_image(camera, spp=RENDER_SPP, seed=RENDER_SEED):
    from renderer.rerender import FitRenderer

    fit = FitRenderer(_spec(camera), resolution=(camera.width, camera.height), spp=spp)
    fit.set(camera=camera)
    return np.ascontiguousarray(fit.render(seed=seed), np.float32)


def _render(dataset, path, seed=RENDER_SEED):
    import OpenImageIO as oiio

    image = _render_image(read_camera(dataset / "truth.json", PHOTO).model, seed=seed)
    out = oiio.ImageOutput.create(str(path))
    assert out is not None
    out.open(str(path), oiio.ImageSpec(image.shape[1], image.shape[0], 3, oiio.FLOAT))
    out.write_image(image)
    out.close()
    return path


def report_on_pair(dataset: Path, folder: Path, render_seed: int = RENDER_SEED) -> tuple[int, Path]:
    """`workbench report` of the dataset's PHOTO and BRACKET against a truth-camera render
    (seed ``render_seed``) into folder/report: (exit code, that folder). benchmarks/
    bench_realisations.py runs it over render realisations to measure the bars' margins."""
    render = _render(dataset, folder / "render.exr", render_seed)
    out = folder / "report"
    code = main(["report", "--photo", str(dataset / "brackets" / PHOTO), "--render", str(render),
                 "--calibration", str(dataset / "truth.json"), "--scene", SCENE, "--out", str(out),
                 "--bracket", *(str(dataset / "brackets" / name) for name in BRACKET)])
    return code, out


@pytest.mark.slow
def test_report_on_a_synthetic_pair_meets_the_bars(tmp_path_factory, tmp_path, capsys):
    dataset = synthetic_dataset(tmp_path_factory, SEED, SCENE)
    code, out = report_on_pair(dataset, tmp_path)
    text = capsys.readouterr()
    assert code == 0, text.err
    report = json.loads((out / "report.json").read_text())
    offsets = report["fringe_offset_px"]
    assert offsets["count"] >= MIN_EDGES, report["cd"]["edge_quality"]
    assert offsets["median"] < MEDIAN_BAR_PX and offsets["p95"] < P95_BAR_PX, offsets
    assert report["prediction_offset_px"]["render"]["median"] < PREDICTION_RENDER_PX, report["prediction_offset_px"]
    photo = report["prediction_offset_px"]["photo"]  # on the photo filled from the bracket: unclipped bands
    assert photo["count"] >= MIN_PREDICTION_EDGES and photo["median"] < PREDICTION_PHOTO_PX, report["prediction_offset_px"]
    used = report["photo_decoding"]["bracket"]
    assert [Path(u["path"]).name for u in used] == ["ev-1.dng", "ev-2.dng", "ev-4.dng", "ev-6.dng"]
    assert report["photo_clipped_pixels"] == 0  # ev-6 holds the brightest band (its peak is about 60x the walls)
    assert {"median", "p95", "count"} <= set(report["fringe_offset_unclipped_px"])
    # the second measure is reported (no bar: issue 15 sets none; tests/reports/test_hue.py checks it against known
    # wavelengths); cornell_cd's clipped first orders leave it few or no crossings here
    assert {"median", "p95", "count"} <= set(report["hue_offset_px"])
    assert report["seconds"] > 0  # recorded; the 30 s bar is benchmarks/bench_report.py's (issue 23: no clock in tests)
    assert sum(f.stat().st_size for f in out.iterdir()) < SIZE_BYTES
    csv_text = (out / "fringes.csv").read_text()
    assert ",R," in csv_text and (",hue," in csv_text or report["hue_offset_px"]["count"] == 0)


def _turned(camera, degrees):
    from scipy.spatial.transform import Rotation

    turn = Rotation.from_rotvec(np.radians([0.0, degrees, 0.0])).as_matrix()
    pose = camera.world_to_camera.copy()
    pose[:3, :3], pose[:3, 3] = turn @ pose[:3, :3], turn @ pose[:3, 3]
    return dataclasses.replace(camera, world_to_camera=pose)


def _wider(camera, degrees):
    fov = 2 * np.arctan(0.5 * camera.width / camera.fx)
    fx = 0.5 * camera.width / np.tan(0.5 * fov + np.radians(degrees) / 2)
    return dataclasses.replace(camera, fx=fx, fy=camera.fy * fx / camera.fx)


KNOWN_ERRORS = {"rotated 0.3 deg": lambda camera: _turned(camera, 0.3), "FOV +0.2 deg": lambda camera: _wider(camera, 0.2)}


@pytest.mark.slow
@pytest.mark.parametrize("error", sorted(KNOWN_ERRORS))
def test_known_camera_error_is_reported_as_the_predicted_offset(tmp_path_factory, error):
    """The calibration is wrong by a known amount (issue 15: the truth camera turned by 0.3 deg,
    or its field of view changed by 0.2 deg): the report's camera is the wrong one, the render
    is made with it and compared with the photo (taken with the truth camera). Edge by edge,
    the measured photo-render offset must be what the grating equation predicts: the offset
    between the prediction for the wrong camera and that for the right one."""
    dataset = synthetic_dataset(tmp_path_factory, SEED, SCENE)
    differences, offsets = known_error_offsets(dataset, error)
    assert len(differences) >= MIN_KNOWN_EDGES
    assert np.median(np.abs(differences)) < realisation_bounds.KNOWN_ERROR_MEDIAN_PX[error]
    if error.startswith("rotated"):
        assert np.median(np.abs(offsets)) > 1.0  # the turn moves the fringes by pixels


def known_error_offsets(dataset: Path, error: str, render_seed: int = RENDER_SEED) -> tuple[list[float], list[float]]:
    """The wrong camera's photo-render offsets, each less the grating equation's prediction
    (render (wrong) - photo (right)), and the offsets themselves."""
    from renderer.trace.prediction import predict
    from reports.compare import images
    from reports.fringes import band_edges as fringes
    from reports.fringes import polar
    from reports.report import _sampled_prediction, measure_fringes

    truth = read_camera(dataset / "truth.json", PHOTO).model
    wrong = KNOWN_ERRORS[error](truth)
    spec = _spec(wrong)
    photo = images.read_photo(dataset / "brackets" / KNOWN_ERROR_PHOTO)
    render = _render_image(wrong, KNOWN_ERROR_SPP, render_seed)
    scale, _ = images.photometric_scale(photo.rgb, render, images.region_masks(spec), photo.clipped)
    right, bad = predict(spec, truth), predict(spec, wrong)
    grids = polar.standard_grids(wrong, bad.cd)
    measured = measure_fringes(bad, photo, render * scale, grids, wrong.fx)["pairs"]["photo_render"]
    predicted = {}
    for grid in grids:
        own = fringes.find_edges(grid, _sampled_prediction(bad, grid), bad.orders)
        true = fringes.find_edges(grid, _sampled_prediction(right, grid), right.orders)
        predicted.update({p.key: p.offset_px for p in fringes.pair_edges(grid, true, own, wrong.fx)})  # wrong - right
    differences = [p.offset_px - predicted[p.key] for p in measured if p.key in predicted]  # render (wrong) - photo (right)
    return differences, [p.offset_px for p in measured]

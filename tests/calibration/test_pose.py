"""Pose and field of view of a scene photo (calibration/pose/calibrate.py, edges.py, scene_model.py).

Fast checks, on images made here:
* the sub-pixel edge finder on exactly area-sampled steps at every orientation;
* the whole fit on an exactly rasterised Cornell box (each pixel the mean of 8 x 8
  sub-samples of flat-shaded walls seen through the true camera, distortion included):
  from a start 1.5 deg and 2 cm off it must come back to the truth, with the intrinsics held
  and with them fitted;
* occlusion by the glass objects; fitted_scene.toml reproduces the fitted camera exactly;
  bad input (black, saturated, wrong size, no camera, a bad intrinsics file) is a
  UserInputError naming the file.

Slow (the draft dataset of `workbench synth cornell_cd --seed 0`, made once per session
and calibrated with `calibrate DATASET` from a copy holding only photos/, brackets/ and
calibration/, so nothing can read its truth.json): view0's and view1's pose and field of
view against truth.json, within bounds set by the errors' spread over render realisations
(tests/calibration_bounds.py: the issue's own bars are missed by 1 realisation in 6 and are
judged in benchmarks/bench_calibration.py), and the reported standard deviations against
the actual errors.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from calibration.pose.calibrate import PoseSettings, Unknowns, calibrate_pose, fit_photo, load_intrinsics
from calibration.pose.edges import edge_offsets, smoothed
from calibration.pose.scene_model import scene_model, visible
from renderer.camera import CameraModel
from renderer.render import with_resolution
from renderer.scene import load_scene, parse_scene
from renderer.trace.geometry import box_walls, light_corners
from tests import calibration_bounds as bounds
from tests import realisation_bounds
from workbench.core.errors import UserInputError

SEED = 0  # seeds 1 and 2 meet issue 14's bars too; seed 5 (the other tests' dataset) misses translation: 1.06 mm
STEP_PX = 0.04              # measured 0.034 px at worst (axis-aligned steps): the 0.1-of-peak floor of the lobe
# An exact image of the box at 320 x 240 (the edge finder's bias there is 0.001-0.01 px per edge): measured
# 0.0016 deg and 0.03 mm with the intrinsics held, 0.010 deg, 0.10 mm, 0.010 deg of FOV and 0.07 px of principal
# point with them fitted (k1 fitted, the truth's k2 = 0.02 not).
RASTER_ROTATION_DEG = 0.03
RASTER_CENTER_M = 3e-4
RASTER_FOV_DEG = 0.03
RASTER_PRINCIPAL_PX = 0.3
RASTER_RESIDUAL_PX = 0.05   # measured 0.019 px: the edges of an exact image agree to a twentieth of a pixel
# The calibrated seed-0 dataset against its truth: bounds over render realisations (tests/calibration_bounds.py;
# issue 14's 0.1 deg, 1 mm, 0.05 deg and 0.5 % are judged over realisations in benchmarks/bench_calibration.py)
ROTATION_DEG = bounds.ROTATION_DEG
TRANSLATION_M = bounds.CENTRE_MM / 1000.0
FOV_DEG = bounds.FOV_DEG
PRINCIPAL_POINT_SHARE = bounds.PRINCIPAL_POINT_PCT / 100.0
# A photo of the scene shows nearly all of the scene's projected edges (coverage, calibration.pose.edge_fit): measured
# 0.989-0.994 on the draft dataset's views (issue 45), 1.0 on the exact raster; below 0.95 the margin to the refusal
# threshold (MIN_COVERAGE = 0.75, tests/calibration/test_pose_refusal.py) would be eroding: a false alarm coming.
SCENE_COVERAGE = 0.95
STD_FACTOR = 4.0            # exact rasters (no noise: round-off only): an error beyond 4 reported stds, a std not honest
# The dataset's photos: an error beyond DATASET_STD_FACTOR reported stds, a std an order of magnitude too small (a
# units slip, a lost term). 4 failed on 1 realisation in 100 or so (cy's error reached 3.46 of its std over 12 render
# realisations, 1.51 +- 0.89: its std is about 1.7x small on this dataset); tests/realisation_bounds.py
DATASET_STD_FACTOR = realisation_bounds.STD_FACTOR


# --------------------------------------------------------------------------------------- helpers


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(np.clip((np.trace(a[:3, :3] @ b[:3, :3].T) - 1) / 2, -1.0, 1.0)))


def center_error_m(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(-a[:3, :3].T @ a[:3, 3] + b[:3, :3].T @ b[:3, 3]))


def fov_deg(width: int, fx: float) -> float:
    return 2 * math.degrees(math.atan(width / (2 * fx)))


def perturbed(camera: CameraModel, rotation_deg: float, shift_m: float, seed: int = 1) -> CameraModel:
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    dR = cv2.Rodrigues(math.radians(rotation_deg) * axis / np.linalg.norm(axis))[0]
    T = camera.world_to_camera.copy()
    center = -T[:3, :3].T @ T[:3, 3] + shift_m * rng.normal(size=3) / math.sqrt(3)
    T[:3, :3] = dR @ T[:3, :3]
    T[:3, 3] = -T[:3, :3] @ center
    return dataclasses.replace(camera, world_to_camera=T)


def area_sampled_step(offset: float, angle_deg: float, size: int = 64, sub: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """A step of 0.1 -> 0.9 whose edge passes ``offset`` px from the image centre along its
    normal at ``angle_deg``; each pixel the mean of sub x sub samples."""
    normal = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))])
    ys, xs = np.mgrid[0:size * sub, 0:size * sub]
    x, y = (xs + 0.5) / sub - 0.5 - size / 2, (ys + 0.5) / sub - 0.5 - size / 2
    fine = np.where(x * normal[0] + y * normal[1] > offset, 0.9, 0.1).astype(np.float32)
    return fine.reshape(size, sub, size, sub).mean(axis=(1, 3)), normal


SHADES = {"floor_white": 0.55, "back_wall_white": 0.45, "left_wall_red": 0.2, "right_wall_green": 0.3,
          "ceiling_white": 0.65}
SUB = 8


def rasterised_box(spec, camera: CameraModel) -> np.ndarray:
    """Flat-shaded walls and the light seen by ``camera`` (distortion included), each pixel
    the mean of SUB x SUB samples: edges exactly where the camera model puts them."""
    from matplotlib.path import Path as Outline

    shape = (camera.height * SUB, camera.width * SUB)
    fine = np.zeros(shape, np.float32)
    polygons = [(box_walls(spec)[name], shade) for name, shade in SHADES.items()] + [(light_corners(spec), 1.0)]
    band_kernel = np.ones((5, 5), np.uint8)
    for quad, shade in polygons:  # a sub-sample takes the shade of the polygon its centre lies in (exact, no dilation)
        t = np.linspace(0, 1, 64, endpoint=False)[:, None]
        outline = camera.project(np.concatenate([quad[i] + t * (quad[(i + 1) % 4] - quad[i]) for i in range(4)]))
        sub = (outline + 0.5) * SUB - 0.5  # sub-sample centres at integers
        inside = np.zeros(shape, np.uint8)
        cv2.fillPoly(inside, [np.rint(sub * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
        band = (cv2.dilate(inside, band_kernel) > 0) & (cv2.erode(inside, band_kernel) == 0)  # where fillPoly may err
        rows, cols = np.nonzero(band)
        exact = inside.astype(bool)
        exact[rows, cols] = Outline(sub).contains_points(np.stack([cols, rows], 1))
        fine[exact] = shade
    return fine.reshape(camera.height, SUB, camera.width, SUB).mean(axis=(1, 3))


class _Photo:
    """The parts of calibration.pose.photo.Photo fit_photo reads."""

    def __init__(self, grey: np.ndarray) -> None:
        self.rgb = np.repeat(grey[..., None], 3, axis=2)
        self.grey = grey
        self.saturated = np.zeros(grey.shape, bool)
        self.path = "rasterised"
        self.exposure_time_s = None
        self.cfa = None
        self.linear = True
        self.width, self.height = grey.shape[1], grey.shape[0]


@pytest.fixture(scope="module")
def box_scene():
    spec = with_resolution(load_scene("cornell_cd"), (320, 240))
    return dataclasses.replace(spec, cds=(), glass=())  # the rasterised box shows neither


# ----------------------------------------------------------------------------------------- fast


@pytest.mark.parametrize("angle_deg", [0.0, 5.0, 17.0, 45.0, 90.0, 133.0])
def test_edge_finder_locates_area_sampled_steps(angle_deg: float) -> None:
    errors = []
    for offset in np.linspace(-0.5, 0.5, 11):
        image, normal = area_sampled_step(offset, angle_deg)
        centre = np.array([32.0, 32.0])
        along = np.array([-normal[1], normal[0]])
        points = np.stack([centre, centre + 5 * along, centre - 3 * along])
        found = edge_offsets(smoothed(image), points, np.repeat(normal[None], 3, 0), 4.0, noise=1e-3)
        assert found.valid.all()
        assert np.all(found.polarity == 1)
        errors.append(np.abs(found.offset - offset).max())
    assert max(errors) < STEP_PX


@pytest.mark.parametrize("free_intrinsics", [False, True])
def test_fit_recovers_the_camera_of_an_exact_box_image(box_scene, free_intrinsics: bool) -> None:
    nominal = box_scene.camera.model
    focal = nominal.fx * 1.02
    truth = dataclasses.replace(nominal, fx=focal, fy=focal, cx=nominal.cx + 3.5, cy=nominal.cy - 2.5,
                                dist=(-0.08, 0.02, 0.0, 0.0, 0.0))  # square pixels, as the free fit assumes
    truth = perturbed(truth, 1.0, 0.01, seed=7)
    image = rasterised_box(box_scene, truth)
    start = perturbed(truth, 1.5, 0.02, seed=3)
    if free_intrinsics:  # from the scene's nominal intrinsics, without distortion (k2 = 0.02 stays unmodelled)
        start = dataclasses.replace(start, fx=nominal.fx, fy=nominal.fx, cx=nominal.cx, cy=nominal.cy, dist=(0.0,) * 5)
    result = fit_photo(_Photo(image), scene_model(box_scene), start, Unknowns(free_intrinsics, 1 if free_intrinsics else 0),
                       PoseSettings(render_check=False))
    fitted = result.camera
    assert rotation_error_deg(fitted.world_to_camera, truth.world_to_camera) < RASTER_ROTATION_DEG
    assert center_error_m(fitted.world_to_camera, truth.world_to_camera) < RASTER_CENTER_M
    assert result.residuals["robust_sigma_px"] < RASTER_RESIDUAL_PX
    assert result.residuals["coverage"] >= SCENE_COVERAGE  # a photo of the scene is not refused (calibration.pose.edge_fit)
    if free_intrinsics:
        assert abs(fov_deg(truth.width, fitted.fx) - fov_deg(truth.width, truth.fx)) < RASTER_FOV_DEG
        assert abs(fitted.cx - truth.cx) < RASTER_PRINCIPAL_PX and abs(fitted.cy - truth.cy) < RASTER_PRINCIPAL_PX
    # the reported uncertainty covers the error (conservative: it allows for per-edge biases of 0.02 px)
    assert rotation_error_deg(fitted.world_to_camera, truth.world_to_camera) < STD_FACTOR * result.std["rotation_total_deg"]


def test_glass_hides_the_crease_behind_it() -> None:
    spec = load_scene("cornell_cd")
    model = scene_model(spec)
    camera = spec.camera.model
    eye = -camera.world_to_camera[:3, :3].T @ camera.world_to_camera[:3, 3]
    cube = np.asarray(spec.glass[0].center)
    behind = eye + eye[1] / (eye[1] - cube[1]) * (cube - eye)  # where the line of sight through the cube meets the floor
    beside = behind + np.array([-0.08, 0.0, 0.0])
    assert visible(np.stack([behind, beside]), eye, model.occluders).tolist() == [False, True]


def test_fitted_scene_reproduces_the_camera_exactly() -> None:
    from calibration.pose.scene_file import fitted_scene_text

    spec = load_scene("cornell_cd")
    camera = dataclasses.replace(perturbed(spec.camera.model, 2.0, 0.03), fx=301.25, fy=302.5, cx=160.1, cy=121.7,
                                 dist=(-0.1, 0.03, 1e-4, -2e-4, 0.0))
    again = parse_scene(fitted_scene_text(spec, camera, 1.75), source="fitted", base_dir=None)
    model = again.camera.model
    assert (model.fx, model.fy, model.dist) == (camera.fx, camera.fy, camera.dist)
    assert model.cx == pytest.approx(camera.cx, abs=1e-9) and model.cy == pytest.approx(camera.cy, abs=1e-9)
    assert np.allclose(model.world_to_camera, camera.world_to_camera, atol=1e-12)
    assert again.camera.exposure == 1.75


@pytest.mark.parametrize(("camera_toml", "field"), [
    ('world_to_camera = [[1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\nfov_deg = 40', "camera.world_to_camera"),
    ('world_to_camera = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]\nfov_deg = 40', "camera.world_to_camera"),
    ('look_at = { origin = [0.28, 0.3, -0.5], target = [0.28, 0.3, 0] }\nfocal_px = [300, 300]\nfov_deg = 40',
     "camera.focal_px"),
])
def test_explicit_camera_fields_are_checked(camera_toml: str, field: str) -> None:
    text = f'[box]\n[light]\n[camera]\nresolution = [64, 48]\n{camera_toml}\n'
    with pytest.raises(UserInputError) as info:
        parse_scene(text, source="bad.toml", base_dir=None)
    assert info.value.field == field and info.value.file == "bad.toml"


def _write_dng(path: Path, raw: np.ndarray) -> Path:
    from datasets_synthetic.dng import DngMetadata, write_dng

    return write_dng(path, raw.astype(np.uint16), DngMetadata())


@pytest.mark.parametrize(("level", "words"), [(512, "black"), (16383, "saturated")])
def test_black_or_saturated_photo_is_a_clear_error(tmp_path: Path, level: int, words: str) -> None:
    photo = _write_dng(tmp_path / "flat.dng", np.full((240, 320), level))
    with pytest.raises(UserInputError, match=words) as info:
        calibrate_pose(photo, "cornell_cd", tmp_path / "out", progress=False)
    assert info.value.file == str(photo)
    assert not (tmp_path / "out").exists()  # nothing written


def test_photo_of_another_size_than_the_intrinsics_is_refused(tmp_path: Path) -> None:
    photo = _write_dng(tmp_path / "small.dng", np.full((240, 320), 4000))
    intrinsics = tmp_path / "intrinsics.json"
    intrinsics.write_text(json.dumps({"width": 640, "height": 480, "fx": 900.0, "fy": 900.0, "cx": 319.5, "cy": 239.5,
                                      "dist": [0, 0, 0, 0, 0]}))
    with pytest.raises(UserInputError, match="size differs") as info:
        calibrate_pose(photo, "cornell_cd", tmp_path / "out", intrinsics=intrinsics, progress=False)
    assert info.value.file == str(photo) and "640 x 480" in str(info.value)


def test_scene_without_a_camera_is_refused(tmp_path: Path) -> None:
    scene = tmp_path / "nocamera.toml"
    scene.write_text("[box]\nmodel = \"cornell\"\n[light]\npower_w = 10.0\n")
    photo = _write_dng(tmp_path / "p.dng", np.full((240, 320), 4000))
    with pytest.raises(UserInputError, match="missing") as info:
        calibrate_pose(photo, scene, tmp_path / "out", progress=False)
    assert info.value.file == str(scene) and info.value.field == "camera"


def test_intrinsics_file_without_a_field_names_it(tmp_path: Path) -> None:
    path = tmp_path / "intrinsics.json"
    path.write_text(json.dumps({"width": 640, "height": 480, "fx": 900.0, "cx": 319.5, "cy": 239.5, "dist": [0] * 5}))
    with pytest.raises(UserInputError) as info:
        load_intrinsics(path)
    assert info.value.file == str(path) and info.value.field == "fy"


# ------------------------------------------------------------------------------ slow: the dataset


def synthetic_dataset(tmp_path_factory) -> Path:
    """`workbench synth cornell_cd --seed SEED` (draft), once per session, shared with
    test_dataset.py, tests/datasets_synthetic/test_synth.py and test_response.py."""
    from tests.conftest import synthetic_dataset as shared

    return shared(tmp_path_factory, SEED)


def calibrated_dataset(tmp_path_factory, dataset: Path | None = None) -> tuple[Path, dict, dict]:
    """`calibrate DATASET` on a copy of the dataset (default: the shared seed-0 one) without its
    truth, once per run, by one xdist worker while the others wait: (out, calibration.json, truth.json)."""
    from filelock import FileLock

    from calibration.dataset import calibrate_dataset

    dataset = dataset or synthetic_dataset(tmp_path_factory)
    out = dataset.parent / "calibrated"
    with FileLock(dataset.parent / "calibrated.lock"):
        _calibrate_once(dataset, out, calibrate_dataset)
    return out, json.loads((out / "calibration.json").read_text()), json.loads((dataset / "truth.json").read_text())


def _calibrate_once(dataset: Path, out: Path, calibrate_dataset) -> None:
    if not (out / "calibration.json").exists():
        blind = dataset.parent / "photos-only"
        blind.mkdir(exist_ok=True)
        for sub in ("photos", "brackets", "calibration"):
            if not (blind / sub).exists():
                (blind / sub).symlink_to(dataset / sub, target_is_directory=True)
        calibrate_dataset(blind, "cornell_cd", out, progress=False)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    return calibrated_dataset(tmp_path_factory)


@pytest.mark.slow
@pytest.mark.parametrize("photo", ["view0.dng", "view1.dng"])
def test_pose_against_truth(calibrated, photo: str) -> None:
    _, result, truth = calibrated
    fitted = np.array(result["camera"]["world_to_camera"][photo])
    true = np.array(truth["camera"]["world_to_camera"][photo])
    assert rotation_error_deg(fitted, true) < ROTATION_DEG
    assert center_error_m(fitted, true) < TRANSLATION_M


@pytest.mark.slow
@pytest.mark.parametrize("photo", ["view0.dng", "view1.dng"])
def test_photos_of_the_scene_show_its_edges(calibrated, photo: str) -> None:
    """The goodness-of-fit test that refuses photos of something else passes the scene's own photos, with margin."""
    _, result, _ = calibrated
    assert result["residuals"][photo]["coverage"] >= SCENE_COVERAGE


@pytest.mark.slow
def test_field_of_view_and_principal_point_against_truth(calibrated) -> None:
    _, result, truth = calibrated
    c, t = result["camera"], truth["camera"]
    assert abs(fov_deg(c["width"], c["fx"]) - fov_deg(t["width"], t["fx"])) < FOV_DEG
    assert abs(fov_deg(c["height"], c["fy"]) - fov_deg(t["height"], t["fy"])) < FOV_DEG
    assert abs(c["cx"] - t["cx"]) < PRINCIPAL_POINT_SHARE * t["width"]
    assert abs(c["cy"] - t["cy"]) < PRINCIPAL_POINT_SHARE * t["height"]


@pytest.mark.slow
@pytest.mark.parametrize("photo", ["view0.dng", "view1.dng"])
def test_reported_uncertainty_covers_the_error(calibrated, photo: str) -> None:
    _, result, truth = calibrated
    fitted = np.array(result["camera"]["world_to_camera"][photo])
    true = np.array(truth["camera"]["world_to_camera"][photo])
    std = result["std"]["poses"][photo]
    assert rotation_error_deg(fitted, true) < DATASET_STD_FACTOR * std["rotation_total_deg"]
    assert center_error_m(fitted, true) < DATASET_STD_FACTOR * float(np.linalg.norm(std["camera_center_m"]))
    assert abs(result["camera"]["cx"] - truth["camera"]["cx"]) < DATASET_STD_FACTOR * result["std"]["cx"]
    assert abs(result["camera"]["cy"] - truth["camera"]["cy"]) < DATASET_STD_FACTOR * result["std"]["cy"]


COARSE_RIGHT_BASIN_PX = 1.5  # view1's coarse answer: 0.66-0.88 px RMS in the right basin, 2.1-2.9 px in the wrong one


@pytest.mark.slow
def test_coarse_fit_is_stable_under_round_off(calibrated) -> None:
    """view1 of the seed-0 dataset, whose capped chamfer cost has a wrong basin that one
    BOBYQA start fell into on 8 of 12 starts differing by 1e-9 in fx (a CI run failed on
    the exposure it then measured): every such start must now end in the right one."""
    from calibration.pose.calibrate import coarse_fit, start_camera
    from calibration.pose.photo import read_photo

    out, _, _ = calibrated
    spec = load_scene("cornell_cd")
    photo = read_photo(out.parent / "dataset" / "photos" / "view1.dng")
    start = start_camera(spec, photo, load_intrinsics(out / "intrinsics.json"))
    model = scene_model(spec)
    for k in range(6):
        nudged = dataclasses.replace(start, fx=start.fx * (1 + 1e-9 * k))
        _, log = coarse_fit(photo.grey, model, nudged, Unknowns(intrinsics=False), PoseSettings())
        assert log[-1]["rms_after_px"] < COARSE_RIGHT_BASIN_PX, (k, [round(level["rms_after_px"], 2) for level in log])


# The joint covariance against the truth, where the scene fit reads it: the CD's rim as the true camera and the
# fitted one project it. The displacement's RMS over the rim must stay within COVER times the RMS of its propagated
# standard deviation (measured 0.32 and 0.54 on seed 0: 0.014 and 0.028 px against 0.045 and 0.052 px; the rim's
# displacement is set by a few camera directions, a chi-square of 2 dof per dof beyond 3.5^2 has probability 5e-6;
# whitening each direction instead is not robust, the true lens's distortion differs from the fitted one's along
# directions the pose's covariance does not hold), and the propagation must be far sharper than the independent
# standard deviations' (0.05 px against 0.85 px at the rim: a turn and a principal point that compensate,
# tests/reports/test_scene_verdict.py).
COVER = 3.5
SHARPER_SHARE = 0.5


def _rim_projection(camera, rim: np.ndarray) -> np.ndarray:
    return camera.project(rim).ravel()


@pytest.mark.slow
@pytest.mark.parametrize("photo", ["view0.dng", "view1.dng"])
def test_the_pose_covariance_covers_where_the_true_camera_puts_the_cd(calibrated, photo: str) -> None:
    from calibration.calibration_file import read_camera
    from renderer.trace.prediction import cd_geometry
    from reports.scene_fit.verdict import moved_by_readout, view_moves

    out, result, truth = calibrated
    joint = result["std"]["poses"][photo]["covariance"]
    matrix = np.asarray(joint["matrix"])
    stds = result["std"]["poses"][photo]
    stated = [*stds["rotation_deg"], *stds["camera_center_m"]]
    np.testing.assert_allclose(np.sqrt(np.diag(matrix))[:6], stated, rtol=1e-9)
    np.testing.assert_allclose(matrix, matrix.T, rtol=0, atol=1e-15 * np.max(np.abs(matrix)))
    assert np.linalg.eigvalsh(matrix).min() > -1e-9 * np.abs(matrix).max()

    fitted = read_camera(out / "calibration.json", photo)
    rim = cd_geometry(load_scene("cornell_cd")).rim_points()[::8]
    t = truth["camera"]
    true = dataclasses.replace(fitted.model, fx=t["fx"], fy=t["fy"], cx=t["cx"], cy=t["cy"], dist=tuple(t["dist"]),
                               world_to_camera=np.array(t["world_to_camera"][photo]))
    displacement = _rim_projection(true, rim) - _rim_projection(fitted.model, rim)

    def propagated(camera_std: dict) -> np.ndarray:
        names, moves, _ = view_moves(camera_std)
        base = _rim_projection(fitted.model, rim)
        columns = [(_rim_projection(moved_by_readout(fitted.model, names, 1e-3 * m), rim) - base) / 1e-3 for m in moves]
        A = np.stack(columns, axis=1)
        return A @ A.T

    spread = float(np.sqrt(np.mean(np.diag(propagated(fitted.std)))))
    assert float(np.sqrt(np.mean(displacement**2))) < COVER * spread
    independent = propagated({k: v for k, v in fitted.std.items() if k != "covariance"})
    assert spread < SHARPER_SHARE * float(np.sqrt(np.mean(np.diag(independent))))

"""Lens models beyond the pinhole (calibration/intrinsics/lens_models.py, lens_choice.py; issue 26, item 1).

Synthetic corners (tests/calibration/lens_views.py: exact projections through a known camera,
0.05 px of Gaussian noise, 12 views reaching into the image corners):

* a wide fisheye (Kannala-Brandt, 135 degrees across the diagonal): fx and fy within 0.5 %,
  the principal point within 2 px (the calibration issue's bars), and the distortion: every
  corner's ray projected through the fitted camera lands within RAY_PX of where the true one
  puts it;
* Mei's omnidirectional camera (xi = 1.2): xi trades with fx and k1 along a shallow valley, so
  what the views fix is fx / (1 + xi), the focal length at the image centre (d pixel / d angle
  on the axis): that within 0.5 %, fx and xi within TRUTH_STDS of their own stated std, the
  principal point within 2 px, the rays as above;
* the rational model recovers a strong pincushion-and-barrel pinhole camera likewise;
* ``--model auto`` picks the pinhole on pinhole data and the fisheye on the wide fisheye's
  (where the pinhole's held-out RMS is 9 x the noise); with three views (none can be held out)
  the pinhole stays unless its in-sample RMS is over 1 px;
* a bad --model value exits 2 with argparse's message; the camera file records the model and
  refuses a wrong number of coefficients;
* the fisheye's stated std of fx (computed here: OpenCV's fisheye gives none) matches the spread of fx
  over repeated noisy fits.
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from calibration.calibration_file import read_camera
from calibration.intrinsics.lens_choice import choose_model, pick
from calibration.intrinsics.lens_models import NOT_WORSE_REL, fit_model
from renderer import lens
from tests.calibration.lens_views import corner_views
from workbench.cli import main
from workbench.core.errors import UserInputError

SIZE = (640, 480)
FOCAL_REL = 0.005     # the calibration issue's bar: fx within 0.5 % (measured 0.02 %, 0.04 %, omnidir centre 0.03 %)
CENTRE_PX = 2.0       # and the principal point within ~2 px (measured 0.03-0.26 px)
RAY_PX = 0.25         # five times the corner noise: the fitted lens maps the covered rays as the true one, largest over
                      # every corner (measured over seeds 1-3: fisheye 0.03-0.09, rational 0.06-0.14, omnidir 0.09-0.17)
TRUTH_STDS = 4.0      # omnidir fx and xi within four of their stated std: the valley is curved, so the linearised std
                      # understates it (measured 1.5 std for seed 1; 3.7 and 0.7 for seeds 2 and 3)
VIEWS = 12


def _camera(f: float, cx: float = 322.0, cy: float = 238.0) -> np.ndarray:
    return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])


FISHEYE = ("fisheye", _camera(330.0), np.array([0.03, -0.01, 0.004, -0.001]), 0.0)
OMNIDIR = ("omnidir", _camera(600.0), np.array([-0.1, 0.03, 0.0005, -0.0005]), 1.2)
PINHOLE = ("pinhole", _camera(500.0), np.array([-0.2, 0.08, 0.0, 0.0, 0.0]), 0.0)
RATIONAL = ("rational", _camera(420.0), np.array([0.4, -0.1, 0.0005, -0.0003, 0.01, 0.7, 0.02, 0.0]), 0.0)


def _ray_error_px(truth, fit, corners) -> float:
    """The distortion compared: each corner's true ray projected through the true and the fitted
    camera, as offsets from each camera's own principal point (a principal point error, checked
    on its own, moves every pixel alike and is taken up by the pose); the largest difference."""
    model, K, dist, xi = truth
    seen = np.concatenate([c.reshape(-1, 2) for c in corners])
    rays = np.c_[lens.normalized(model, seen, K, dist, xi), np.ones(len(seen))]
    exact = lens.project(model, rays, np.zeros(3), np.zeros(3), K, dist, xi) - K[:2, 2]
    fitted = lens.project(fit.model, rays, np.zeros(3), np.zeros(3), fit.K, fit.dist, fit.xi) - fit.K[:2, 2]
    return float(np.max(np.linalg.norm(fitted - exact, axis=1)))


@pytest.mark.parametrize("truth", [FISHEYE, RATIONAL], ids=["fisheye", "rational"])
def test_wide_lens_is_recovered(truth):
    model, K, dist, xi = truth
    points, corners = corner_views(model, K, dist, xi, SIZE, VIEWS, seed=1)
    fit = fit_model(points, corners, SIZE, cv2.CALIB_FIX_K3, model)
    assert fit.K[0, 0] == pytest.approx(K[0, 0], rel=FOCAL_REL) and fit.K[1, 1] == pytest.approx(K[1, 1], rel=FOCAL_REL)
    assert np.hypot(*(fit.K[:2, 2] - K[:2, 2])) < CENTRE_PX
    assert _ray_error_px(truth, fit, corners) < RAY_PX
    assert fit.rms_px < 2 * 0.05 and len(fit.dist) == lens.LENS_MODELS[model].count
    assert fit.std[0] > 0 and np.all(np.isfinite(fit.std))   # stated uncertainty exists for every model


def test_omnidirectional_camera_is_recovered():
    model, K, dist, xi = OMNIDIR
    points, corners = corner_views(model, K, dist, xi, SIZE, VIEWS, seed=1)
    fit = fit_model(points, corners, SIZE, 0, model)
    assert fit.K[0, 0] / (1 + fit.xi) == pytest.approx(K[0, 0] / (1 + xi), rel=FOCAL_REL)
    assert abs(fit.K[0, 0] - K[0, 0]) < TRUTH_STDS * fit.std[0] and abs(fit.xi - xi) < TRUTH_STDS * fit.xi_std
    assert np.hypot(*(fit.K[:2, 2] - K[:2, 2])) < CENTRE_PX
    assert _ray_error_px(OMNIDIR, fit, corners) < RAY_PX


def test_auto_picks_the_pinhole_on_pinhole_data_and_the_fisheye_on_a_wide_fisheye():
    pinhole = choose_model(*corner_views(*PINHOLE, SIZE, VIEWS, seed=2), SIZE, cv2.CALIB_FIX_K3)
    assert pinhole.model == "pinhole" and pinhole.held_out, pinhole.why
    fisheye = choose_model(*corner_views(*FISHEYE, SIZE, VIEWS, seed=2), SIZE, cv2.CALIB_FIX_K3)
    assert fisheye.model == "fisheye", fisheye.why
    assert fisheye.scores["pinhole"] > 3 * fisheye.scores["fisheye"]   # the pinhole cannot follow a 135-degree lens
    assert "fisheye" in fisheye.to_json()["why"] and set(fisheye.to_json()["rms_px"]) == set(lens.LENS_MODELS)


def test_the_rule_prefers_the_simplest_model_within_tolerance_but_never_a_poor_one():
    close = 1 + NOT_WORSE_REL / 2
    assert pick({"pinhole": 0.10 * close, "fisheye": 0.10, "omnidir": 0.10, "rational": 0.10})[0] == "pinhole"
    assert pick({"pinhole": 0.20, "fisheye": 0.10, "omnidir": 0.10, "rational": 0.10 / close})[0] == "fisheye"
    assert pick({"pinhole": 0.20, "fisheye": 0.10, "omnidir": 0.10, "rational": 0.09})[0] == "rational"   # 10 % better
    # within tolerance but over 1 px while a richer model does better: not chosen
    assert pick({"pinhole": 1.2 * close, "fisheye": 1.2, "omnidir": 1.2, "rational": 1.2})[0] == "fisheye"
    assert pick({"pinhole": float("inf"), "fisheye": 0.3, "omnidir": 0.3, "rational": 0.3})[0] == "fisheye"


def test_a_bad_model_value_exits_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["calibrate", "intrinsics", str(tmp_path / "a.png"), "--board", "9x6", "--square-mm", "25",
              "--out", str(tmp_path / "i.json"), "--model", "kannala"])
    assert stop.value.code == 2 and "--model" in capsys.readouterr().err
    with pytest.raises(UserInputError, match="unknown lens model"):
        fit_model([], [], SIZE, 0, "kannala")


def test_the_camera_file_carries_the_model(tmp_path):
    camera = {"width": 640, "height": 480, "fx": 600.0, "fy": 600.0, "cx": 322.0, "cy": 238.0, "model": "omnidir",
              "xi": 1.2, "dist": [-0.1, 0.03, 0.0005, -0.0005], "world_to_camera": np.eye(4).tolist()}
    path = tmp_path / "calibration.json"
    path.write_text(json.dumps({"camera": camera}))
    got = read_camera(path, "photo.dng")
    assert got.model.model == "omnidir" and got.model.xi == 1.2 and got.summary()["model"] == "omnidir"
    point = np.array([[0.3, -0.2, 1.0]])
    expected = lens.project("omnidir", point, np.zeros(3), np.zeros(3), OMNIDIR[1], OMNIDIR[2], 1.2)
    assert np.allclose(got.model.project(point), expected, atol=1e-9)   # the file's camera is the same projection
    path.write_text(json.dumps({"camera": dict(camera, model="fisheye")}))   # 4 coefficients, but xi given
    with pytest.raises(UserInputError, match="camera.xi"):
        read_camera(path, "photo.dng")
    path.write_text(json.dumps({"camera": dict(camera, model="rational", xi=0.0)}))
    with pytest.raises(UserInputError, match="8 numbers"):
        read_camera(path, "photo.dng")


def test_three_views_keep_the_pinhole_unless_it_fits_worse_than_a_pixel():
    # in sample a richer model always fits better: only the 1 px rule may move the choice (three views: no fold
    # can be held out, two views do not determine a camera)
    pinhole = choose_model(*corner_views(*PINHOLE, SIZE, 3, seed=4), SIZE, cv2.CALIB_FIX_K3)
    assert pinhole.model == "pinhole" and not pinhole.held_out and "in-sample" in pinhole.why
    assert pick({"pinhole": 0.10, "fisheye": 0.05, "omnidir": 0.05, "rational": 0.04}, float("inf"))[0] == "pinhole"
    assert pick({"pinhole": 1.5, "fisheye": 0.05, "omnidir": 0.05, "rational": 0.04}, float("inf"))[0] == "fisheye"


HONEST_STD = (0.6, 1.5)   # spread of fx over TRIALS noisy fits of the same views / the median stated std: 1 within the
                          # sampling error of 20 trials (measured 0.95 fisheye; omnidir 0.86, not run: 10 s)
TRIALS = 20


def test_the_fisheye_standard_deviation_matches_the_spread_over_noisy_fits():
    model, K, dist, xi = FISHEYE
    points, exact = corner_views(model, K, dist, xi, SIZE, VIEWS, seed=1, noise_px=0.0)
    rng = np.random.default_rng(5)
    fx, stated = [], []
    for _ in range(TRIALS):
        noisy = [(c + rng.normal(0.0, 0.05, c.shape)).astype(np.float32) for c in exact]
        fit = fit_model(points, noisy, SIZE, 0, model)
        fx.append(fit.K[0, 0])
        stated.append(fit.std[0])
    ratio = np.std(fx, ddof=1) / np.median(stated)
    assert HONEST_STD[0] < ratio < HONEST_STD[1], ratio

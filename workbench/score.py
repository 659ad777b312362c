"""``workbench score RUN --truth DATASET/truth.json``: a verify run against a synthetic dataset's truth.

The calibration's errors (``calibration_errors``, also used by benchmarks/bench_calibration.py):

* rotation (deg): the angle of R_fit R_true^T, per photo;
* camera centre (mm): | C_fit - C_true | with C = -R^T t, per photo;
* field of view (deg): horizontal and vertical, 2 atan(size / 2 f), the larger difference;
* principal point (% of the image's width or height), the larger;
* exposure x light power (%): the fitted photometric scale against the one the synthetic
  sensor applied (datasets_synthetic.sensor: light scale x exposure time x electrons per
  unit x gain / (white - black)), per photo;
* response RMS (%): the fitted curve against the hidden one in normalised value over
  0.05-0.95 (calibration.response.calibrate.response_rms);

with the fringe offsets of each photo's report (report.json's fringe_offset_px). Written
to RUN/score.json. Only ``score`` reads the truth; ``verify`` never does.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from calibration.pose.study import centre_error_mm, expected_exposure_scale, fov_deg, rotation_error_deg
from calibration.response.calibrate import response_rms
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text
from workbench.verify_run import read_record

SCORE_FORMAT = "workbench-score"
WORST_KEYS = ("rotation_deg", "centre_mm", "fov_deg", "principal_point_pct", "exposure_light_pct", "response_rms_pct")


def calibration_errors(result: dict, truth: dict) -> dict[str, Any]:
    """calibration.json's ``result`` against truth.json's ``truth`` (module docstring): the worst
    photo's value of each error, and ``per_photo`` ones."""
    c, t = result["camera"], truth["camera"]
    per_photo: dict[str, dict[str, Any]] = {}
    for photo in sorted(c["world_to_camera"]):
        fitted, true = np.array(c["world_to_camera"][photo]), np.array(t["world_to_camera"][photo])
        scale = (result.get("exposure_scale") or {}).get(photo)
        per_photo[photo] = {"rotation_deg": rotation_error_deg(fitted, true), "centre_mm": centre_error_mm(fitted, true),
                            "exposure_light_pct": None if scale is None
                            else 100 * abs(scale / expected_exposure_scale(truth, photo) - 1)}
    errors: dict[str, Any] = {
        "rotation_deg": max(float(p["rotation_deg"]) for p in per_photo.values()),
        "centre_mm": max(float(p["centre_mm"]) for p in per_photo.values()),
        "fov_deg": max(abs(fov_deg(c["width"], c["fx"]) - fov_deg(t["width"], t["fx"])),
                       abs(fov_deg(c["height"], c["fy"]) - fov_deg(t["height"], t["fy"]))),
        "principal_point_pct": 100 * max(abs(c["cx"] - t["cx"]) / t["width"], abs(c["cy"] - t["cy"]) / t["height"]),
        "exposure_light_pct": max((float(p["exposure_light_pct"]) for p in per_photo.values()
                                   if p["exposure_light_pct"] is not None), default=None),
        "response_rms_pct": (100 * response_rms(result["response"]["points"], truth["response"]["points"])
                             if (result.get("response") or {}).get("points") else None),
    }
    return errors | {"per_photo": per_photo}


def _read_json(path: Path, what: str) -> dict:
    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise UserInputError(f"cannot read {what} ({exc.strerror})", file=path) from None
    except ValueError as exc:
        raise UserInputError(f"{what} is not JSON ({exc})", file=path) from None
    if not isinstance(data, dict):
        raise UserInputError(f"{what} is not a JSON object", file=path)
    return data


CAMERA_NUMBERS = ("width", "height", "fx", "fy", "cx", "cy")


def _check_camera(data: dict, path: Path, what: str, photos: list[str] | None = None) -> list[str]:
    """``data['camera']`` holds the numbers the score compares and a 4 x 4 world_to_camera per
    photo (of ``photos``, or every one given); the photos it has."""
    camera = data.get("camera")
    if not isinstance(camera, dict):
        raise UserInputError(f"{what} has no camera", file=path, field="camera",
                             expected="an object with width, height, fx, fy, cx, cy and world_to_camera")
    for key in CAMERA_NUMBERS:
        if isinstance(camera.get(key), bool) or not isinstance(camera.get(key), (int, float)):
            raise UserInputError(f"{what} has no number here", file=path, field=f"camera.{key}", expected="a number",
                                 got=camera.get(key))
    poses = camera.get("world_to_camera")
    if not isinstance(poses, dict) or not poses:
        raise UserInputError(f"{what} has no camera poses", file=path, field="camera.world_to_camera",
                             expected="an object: photo file name -> 4 x 4 matrix")
    for photo in poses if photos is None else [p for p in photos if p in poses]:
        try:
            ok = np.asarray(poses[photo], dtype=float).shape == (4, 4)
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise UserInputError(f"{what}'s pose is not a 4 x 4 matrix of numbers", file=path,
                                 field=f"camera.world_to_camera.{photo}", expected="[[4 numbers] x 4]")
    return sorted(poses)


def _check_truth(truth: dict, path: Path, photos: list[str]) -> None:
    for key in ("camera", "sensor", "light_power_scale", "exposure_time_s", "response"):
        if key not in truth:
            raise UserInputError("not a synthetic dataset's truth", file=path, field=key,
                                 expected="truth.json as `workbench synth` writes it")
    _check_camera(truth, path, "the truth", photos)
    missing = [p for p in photos if p not in truth["camera"]["world_to_camera"]]
    if missing:
        raise UserInputError(f"the truth has no camera for the run's photos {', '.join(missing)}", file=path,
                             field="camera.world_to_camera", expected="the truth of the dataset the run calibrated")


def score_run(run: str | Path, truth_path: str | Path) -> dict[str, Any]:
    """Compare RUN's calibration and reports with the truth; writes and returns RUN/score.json's content."""
    root, truth_path = Path(run), Path(truth_path)
    record = read_record(root)
    if record is None:
        raise UserInputError("not a verify run (no run.json written by `workbench verify`)", file=root / "run.json",
                             expected="the --out folder of a `workbench verify` run")
    if record.get("stages", {}).get("calibration", {}).get("status") != "done":
        raise UserInputError("the run's calibration has not finished", file=root / "run.json",
                             field="stages.calibration.status", expected="done (run `workbench verify` to the end)")
    calibration_path = root / "calibration" / "calibration.json"
    calibration = _read_json(calibration_path, "the run's calibration")
    photos = _check_camera(calibration, calibration_path, "the run's calibration")
    truth = _read_json(truth_path, "the truth")
    _check_truth(truth, truth_path, photos)
    try:
        errors = calibration_errors(calibration, truth)
    except (KeyError, TypeError, ValueError, IndexError, ZeroDivisionError) as exc:  # a field edited or from another version
        raise UserInputError(f"the score cannot read a field of the truth or of the run's calibration "
                             f"({type(exc).__name__}: {exc})", file=f"{truth_path} or {calibration_path}",
                             expected="truth.json as `workbench synth` writes it and calibration.json as "
                                      "`workbench verify` writes it") from None
    photos = (record.get("summary") or {}).get("photos", {})
    score = {"format": SCORE_FORMAT, "run": str(root), "truth": str(truth_path), "calibration": errors,
             "fringe_offset_px": {name: p.get("fringe_offset_px") for name, p in photos.items()}}
    atomic_write_text(root / "score.json", json.dumps(score, indent=2) + "\n")
    return score


def format_score(score: dict[str, Any]) -> str:
    """The score as printed by ``workbench score``."""
    e = score["calibration"]
    lines = [f"{score['run']} against {score['truth']}:"]
    for key, label, unit in (("rotation_deg", "rotation", "deg"), ("centre_mm", "camera centre", "mm"),
                             ("fov_deg", "field of view", "deg"), ("principal_point_pct", "principal point", "%"),
                             ("exposure_light_pct", "exposure x light", "%"), ("response_rms_pct", "response RMS", "%")):
        value = e[key]
        lines.append(f"  {label:<18} {'-' if value is None else format(value, '.3g')} {unit}")
    for photo, p in e["per_photo"].items():
        exposure = "-" if p["exposure_light_pct"] is None else f"{p['exposure_light_pct']:.3g} %"
        lines.append(f"  {photo}: rotation {p['rotation_deg']:.3g} deg, centre {p['centre_mm']:.3g} mm, "
                     f"exposure x light {exposure}")
    for photo, fo in score["fringe_offset_px"].items():
        text = (f"median {fo['median']:.2f} px, p95 {fo['p95']:.2f} px over {fo.get('count')} band edges"
                if fo and fo.get("median") is not None else "no band edge seen in both photo and render")
        lines.append(f"  {photo}: fringe offset photo-render {text}")
    return "\n".join(lines)

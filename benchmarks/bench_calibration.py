"""Benchmark: `calibrate DATASET` against the truth of synthetic datasets (``make bench``).

For each seed: `workbench synth cornell_cd --seed S` (draft), then `calibrate DATASET` on a
copy holding only photos/, brackets/ and calibration/ (calibration never sees truth.json),
then its results against truth.json, with issue 14's bars: rotation < 0.1 deg, camera
centre < 1 mm, field of view < 0.05 deg, principal point < 0.5 %, exposure x light power
within 1 %, response RMS < 1 % over normalised values 0.05-0.95, under 2 minutes.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

BARS = {"rotation_deg": 0.1, "centre_mm": 1.0, "fov_deg": 0.05, "principal_point_pct": 0.5,
        "exposure_light_pct": 1.0, "response_rms_pct": 1.0, "seconds": 120.0}


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(float(np.clip((np.trace(a[:3, :3] @ b[:3, :3].T) - 1) / 2, -1.0, 1.0))))


def centre_error_mm(a: np.ndarray, b: np.ndarray) -> float:
    return 1e3 * float(np.linalg.norm(-a[:3, :3].T @ a[:3, 3] + b[:3, :3].T @ b[:3, 3]))


def fov_deg(size: int, focal: float) -> float:
    return 2 * math.degrees(math.atan(size / (2 * focal)))


def expected_scale(truth: dict, photo: str) -> float:
    """The synthetic photo's normalised raw value per unit of the scene file's render (datasets_synthetic.sensor)."""
    sensor = truth["sensor"]
    return (truth["light_power_scale"] * truth["exposure_time_s"][photo] * sensor["electrons_per_unit"] * sensor["gain"]
            / (sensor["white_level"] - sensor["black_level"]))


def errors(result: dict, truth: dict, seconds: float) -> dict:
    from calibration.response import response_rms

    c, t = result["camera"], truth["camera"]
    photos = sorted(c["world_to_camera"])
    poses = [(np.array(c["world_to_camera"][p]), np.array(t["world_to_camera"][p])) for p in photos]
    return {
        "rotation_deg": max(rotation_error_deg(a, b) for a, b in poses),
        "centre_mm": max(centre_error_mm(a, b) for a, b in poses),
        "fov_deg": max(abs(fov_deg(c["width"], c["fx"]) - fov_deg(t["width"], t["fx"])),
                       abs(fov_deg(c["height"], c["fy"]) - fov_deg(t["height"], t["fy"]))),
        "principal_point_pct": 100 * max(abs(c["cx"] - t["cx"]) / t["width"], abs(c["cy"] - t["cy"]) / t["height"]),
        "exposure_light_pct": 100 * max(abs(result["exposure_scale"][p] / expected_scale(truth, p) - 1) for p in photos),
        "response_rms_pct": 100 * response_rms(result["response"]["points"], truth["response"]["points"]),
        "seconds": seconds,
    }


def run_seed(seed: int, work: Path) -> dict:
    from calibration.dataset import calibrate_dataset
    from datasets_synthetic.synth import synth

    dataset = work / f"seed{seed}" / "dataset"
    synth("cornell_cd", dataset, seed=seed, progress=False)
    blind = work / f"seed{seed}" / "photos-only"
    blind.mkdir()
    for sub in ("photos", "brackets", "calibration"):
        (blind / sub).symlink_to(dataset / sub, target_is_directory=True)
    start = time.perf_counter()
    result = calibrate_dataset(blind, "cornell_cd", work / f"seed{seed}" / "calibrated", progress=False)
    seconds = time.perf_counter() - start
    return errors(result, json.loads((dataset / "truth.json").read_text()), seconds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0,1,2", help="comma-separated dataset seeds")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench_calibration-"))
    try:
        print("calibrate DATASET on draft synthetic datasets of cornell_cd, against their truth "
              "(worst photo of each dataset; bar in brackets)")
        print(f"{'seed':>4} " + " ".join(f"{k:>20}" for k in BARS))
        print(f"{'':>4} " + " ".join(f"{'(< ' + format(v, 'g') + ')':>20}" for v in BARS.values()))
        for seed in (int(s) for s in args.seeds.split(",")):
            e = run_seed(seed, work)
            marks = {k: "" if e[k] < BARS[k] else " MISS" for k in BARS}
            print(f"{seed:>4} " + " ".join(f"{format(e[k], '.3g') + marks[k]:>20}" for k in BARS), flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()

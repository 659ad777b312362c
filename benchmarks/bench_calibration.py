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
import shutil
import tempfile
import time
from pathlib import Path

BARS = {"rotation_deg": 0.1, "centre_mm": 1.0, "fov_deg": 0.05, "principal_point_pct": 0.5,
        "exposure_light_pct": 1.0, "response_rms_pct": 1.0, "seconds": 120.0}


def errors(result: dict, truth: dict, seconds: float) -> dict:
    """The worst photo's errors (workbench.score.calibration_errors, which `workbench score` prints too)."""
    from workbench.score import calibration_errors

    return {k: v for k, v in calibration_errors(result, truth).items() if k != "per_photo"} | {"seconds": seconds}


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

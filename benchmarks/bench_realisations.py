"""Benchmark: the suite's statistical checks on the shared seed-0 dataset, over render realisations.

The suite asserts bars on one synthetic dataset (seed 0, draft), whose renders carry Monte
Carlo noise; another realisation of that noise (synth's ``render_seed``: the same hidden
camera, poses, exposures and sensor noise streams) is what another machine could as well
have drawn. This benchmark makes the dataset again for each render seed and computes what
the tests compute on it, with the tests' own code:

- tests/workbench/test_verify.py: `verify` at 4 spp; the scene fit's verdict, its Wald
  p-value, the file's band-edge median, each fitted component's move from the file's value
  (in its units and in its standard deviations; issue 25 allows 3);
- tests/calibration/test_pose.py::test_reported_uncertainty_covers_the_error: each photo's
  error in its reported standard deviations (rotation, camera centre, cx, cy);
- tests/reports/test_report_synthetic.py: the photo-render band-edge offsets (median, p95,
  count), the prediction's, and the known camera errors' differences from the grating
  equation, against a truth-camera render whose seed changes with the realisation;
- tests/renderer/test_render_study.py (``--study-seeds``): the study's tiny configuration at
  other seeds (RenderStudyConfig.seed): the orderings as ratios (improved's error at 128 spp
  over its error at 8 and over paper's; paper's colour shift at the smallest Delta over the
  largest; each must stay under 1) and the furnace energies.

It prints each quantity per realisation, then its spread: mean +- SD, the test's bound
(tests/realisation_bounds.py) and the issue's bar in SDs and the chance that one more
realisation crosses each (Student's t predictive, n - 1 degrees of freedom: the SD is itself
estimated). Rows are checkpointed to WORK/rows.json,
so a killed run resumes. ``python -m benchmarks.bench_realisations --work DIR
--render-seeds 0,1,...,7`` (about 6 minutes a realisation on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from tests import realisation_bounds as rb
from workbench.core.files import atomic_write_text

SEED = 0  # the suite's shared dataset
VERIFY_SPP = 4  # tests/workbench/test_verify.py's SPP
# quantity: (bound, "upper" if the test asserts value < bound, "lower" if value > bound): the tests' bounds
# (tests/realisation_bounds.py); BARS: the issues' own bars, judged here over realisations
BOUNDS: dict[str, tuple[float, str]] = {
    "fit_period_move_um": (rb.FIT_MOVE["cd[0].structure.period:value"], "upper"),
    "fit_tilt_move_deg": (min(rb.FIT_MOVE["cd[0].normal:tilt_e1"], rb.FIT_MOVE["cd[0].normal:tilt_e2"]), "upper"),
    "fit_light_move_m": (min(rb.FIT_MOVE["light.center:x"], rb.FIT_MOVE["light.center:z"]), "upper"),
    "pose_rotation_in_std": (rb.STD_FACTOR, "upper"),  # test_pose's DATASET_STD_FACTOR (worst photo)
    "pose_centre_in_std": (rb.STD_FACTOR, "upper"),
    "pose_cx_in_std": (rb.STD_FACTOR, "upper"),
    "pose_cy_in_std": (rb.STD_FACTOR, "upper"),
    "pair_median_px": (rb.PAIR_MEDIAN_PX, "upper"),
    "pair_p95_px": (rb.PAIR_P95_PX, "upper"),
    "pair_count": (8, "lower"),
    "prediction_render_median_px": (rb.PREDICTION_RENDER_MEDIAN_PX, "upper"),
    "prediction_photo_median_px": (rb.PREDICTION_PHOTO_MEDIAN_PX, "upper"),
    "prediction_photo_count": (5, "lower"),
    "known_rotated_median_px": (rb.KNOWN_ERROR_MEDIAN_PX["rotated 0.3 deg"], "upper"),
    "known_fov_median_px": (rb.KNOWN_ERROR_MEDIAN_PX["FOV +0.2 deg"], "upper"),
    "known_rotated_offset_px": (1.0, "lower"),
    "known_count": (20, "lower"),
}
BARS: dict[str, tuple[float, str]] = {
    "fit_p_value": (1e-3, "lower"),  # reports.scene_fit.verdict.ALPHA: consistent needs p >= alpha (judged on -log10 p)
    "fit_file_median_px": (0.5, "upper"),  # REMOVED_MEDIAN_PX: consistent needs the file's edges <= 0.5 px
    "fit_max_abs_sigma": (3.0, "upper"),  # issue 25: every component within 3 std
    "pose_cy_in_std": (4.0, "upper"),  # an honest std: 4 std are rarely crossed
    "pair_median_px": (0.5, "upper"),  # issue 15's bars
    "pair_p95_px": (1.5, "upper"),
    "prediction_render_median_px": (0.5, "upper"),
    "prediction_photo_median_px": (0.5, "upper"),
    "known_rotated_median_px": (0.5, "upper"),
    "known_fov_median_px": (0.5, "upper"),
}
STUDY_BOUNDS: dict[str, tuple[float, str]] = {
    "improved_128_over_8": (1.0, "upper"),
    "improved_over_paper_128": (1.0, "upper"),
    "shift_small_over_large_delta": (1.0, "upper"),
    "improved_energy_error": (0.01, "upper"),  # TOLERANCE_ENERGY, on |energy - 1|
    "paper_energy": (0.95, "lower"),  # PAPER_ENERGY_BAND, on the median of means
    "paper_energy_upper": (1.1, "upper"),
}


def make_dataset(folder: Path, render_seed: int) -> Path:
    from datasets_synthetic.synth import synth

    dataset = folder / "dataset"
    if not (dataset / "truth.json").exists():
        synth("cornell_cd", dataset, seed=SEED, progress=False, render_seed=render_seed)
    return dataset


def verify_numbers(dataset: Path, out: Path) -> dict[str, float]:
    """What test_verify's fit test and test_pose's uncertainty test read, on one verify run."""
    from workbench.verify import VerifySettings, verify

    if not (out / "run.json").exists() or not (out / "fit" / "scene_fit.json").exists():
        verify(dataset, "cornell_cd", out, VerifySettings(spp=VERIFY_SPP, progress=False))
    fit = json.loads((out / "fit" / "scene_fit.json").read_text())
    std = np.concatenate([np.atleast_1d(p["std"]) for p in fit["parameters"].values()])
    sigmas = (np.array(fit["values"]) - np.array(fit["nominal_values"])) / std
    test = fit["verdict"]["test"]
    combined = test["noise_and_camera"] or test["noise_only"]
    move = dict(zip(fit["components"], np.abs(np.array(fit["values"]) - np.array(fit["nominal_values"])), strict=True))
    numbers = {"fit_consistent": float(fit["verdict"]["verdict"] == "consistent"),
               "fit_model": float(fit["verdict"]["verdict"] == "model"),
               "fit_p_value": combined["p_value"], "fit_file_median_px": _file_median(fit),
               "fit_max_abs_sigma": float(np.max(np.abs(sigmas))),
               "fit_period_move_um": float(move["cd[0].structure.period:value"]),
               "fit_tilt_move_deg": float(max(move["cd[0].normal:tilt_e1"], move["cd[0].normal:tilt_e2"])),
               "fit_light_move_m": float(max(move["light.center:x"], move["light.center:z"]))}
    calibration = json.loads((out / "calibration" / "calibration.json").read_text())
    return numbers | pose_in_std(calibration, json.loads((dataset / "truth.json").read_text()))


def _file_median(fit: dict) -> float:
    """The scene file's band-edge residual median (the verdict's ``residuals_before_px``)."""
    return float(fit["verdict"]["residuals_before_px"]["median"])


def pose_in_std(result: dict, truth: dict) -> dict[str, float]:
    """The worst photo's errors in reported standard deviations (test_pose's STD_FACTOR check)."""
    from tests.calibration.test_pose import center_error_m, rotation_error_deg

    rows = []
    for photo, fitted in result["camera"]["world_to_camera"].items():
        fitted, true = np.array(fitted), np.array(truth["camera"]["world_to_camera"][photo])
        std = result["std"]["poses"][photo]
        rows.append((rotation_error_deg(fitted, true) / std["rotation_total_deg"],
                     center_error_m(fitted, true) / float(np.linalg.norm(std["camera_center_m"]))))
    c, t = result["camera"], truth["camera"]
    return {"pose_rotation_in_std": max(r[0] for r in rows), "pose_centre_in_std": max(r[1] for r in rows),
            "pose_cx_in_std": abs(c["cx"] - t["cx"]) / result["std"]["cx"],
            "pose_cy_in_std": abs(c["cy"] - t["cy"]) / result["std"]["cy"]}


def report_numbers(dataset: Path, folder: Path, render_seed: int) -> dict[str, float]:
    """What test_report_synthetic reads, its render seeded apart from the photo's."""
    from tests.reports import test_report_synthetic as t

    seed = t.RENDER_SEED + render_seed
    report_json = folder / "report" / "report.json"
    if not report_json.exists():
        code, _ = t.report_on_pair(dataset, folder, seed)
        if code != 0:
            raise RuntimeError(f"workbench report failed on {dataset} (exit {code})")
    report = json.loads(report_json.read_text())
    offsets, prediction = report["fringe_offset_px"], report["prediction_offset_px"]
    numbers = {"pair_median_px": offsets["median"], "pair_p95_px": offsets["p95"], "pair_count": offsets["count"],
               "prediction_render_median_px": prediction["render"]["median"],
               "prediction_photo_median_px": prediction["photo"]["median"],
               "prediction_photo_count": prediction["photo"]["count"]}
    counts = []
    for error, key in (("rotated 0.3 deg", "known_rotated"), ("FOV +0.2 deg", "known_fov")):
        differences, measured = t.known_error_offsets(dataset, error, seed)
        numbers[f"{key}_median_px"] = float(np.median(np.abs(differences)))
        counts.append(len(differences))
        if key == "known_rotated":
            numbers["known_rotated_offset_px"] = float(np.median(np.abs(measured)))
    return numbers | {"known_count": min(counts)}


def realisation(work: Path, render_seed: int) -> dict[str, float]:
    folder = work / f"render{render_seed}"
    dataset = make_dataset(folder, render_seed)
    return verify_numbers(dataset, folder / "verify") | report_numbers(dataset, folder, render_seed)


def study_numbers(work: Path, seed: int) -> dict[str, float]:
    """test_render_study's configuration at another seed: its orderings as ratios, its energies."""
    import dataclasses

    from renderer.render_study import RenderStudyConfig, run_render_study
    from renderer.variant import set_variant

    set_variant()
    cfg = RenderStudyConfig(resolution=(160, 120), spp_steps=(8, 128), reference_spp=512, deltas=(0.02, 0.5),
                            delta_spp=512, furnace_samples=2_000_000)  # test_render_study's
    data = run_render_study("cornell_cd", work / f"study{seed}", dataclasses.replace(cfg, seed=seed), progress=False)
    errors = {(r["mode"], r["spp"]): r["relative_rms_error"] for r in data["error_vs_time"]}
    energy = {e["mode"]: e["energy"] for e in data["energy"]}
    robust = {e["mode"]: e["energy_median_of_means"] for e in data["energy"]}
    shifts = [b["chromaticity_shift"] for b in data["delta_bias"]]
    return {"improved_128_over_8": errors["improved", 128] / errors["improved", 8],
            "improved_over_paper_128": errors["improved", 128] / errors["paper", 128],
            "shift_small_over_large_delta": shifts[0] / shifts[-1],
            "improved_energy_error": abs(energy["improved"] - 1), "paper_energy": robust["paper"],
            "paper_energy_upper": robust["paper"],
            "paper_plain_mean_energy": energy["paper"]}


def spread_line(key: str, values: np.ndarray, bounds: dict[str, tuple[float, str]] = BOUNDS) -> str:
    """mean +- SD, the bound's distance in SD and Student's t predictive tail beyond it."""
    from scipy.stats import t

    bound, side = bounds[key]
    n = len(values)
    mean, sd = float(values.mean()), float(values.std(ddof=1)) if n > 1 else float("nan")
    if key == "fit_p_value":  # the p-value is uniform under a correct noise model: judge its -log10
        values = -np.log10(np.maximum(values, 1e-300))
        mean, sd, bound, side = float(values.mean()), float(values.std(ddof=1)), 3.0, "upper"
    distance = (bound - mean) / sd if side == "upper" else (mean - bound) / sd
    tail = float(t.sf(distance / math.sqrt(1 + 1 / n), n - 1)) if n > 1 and sd > 0 else float("nan")
    op = "<" if side == "upper" else ">"
    return (f"  {key:>30}: {mean:.3g} +- {sd:.2g} (range {values.min():.3g}..{values.max():.3g})  "
            f"bound {op} {bound:g} at {distance:.1f} SD  P(cross) t {tail:.1g}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, required=True, help="folder for the datasets and runs (resumable)")
    parser.add_argument("--render-seeds", default="0,1,2,3,4,5,6,7",
                        help="comma-separated render seeds of the seed-0 dataset (0 is the suite's own)")
    parser.add_argument("--study-seeds", default="",
                        help="comma-separated seeds of test_render_study's configuration (instead of the dataset)")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    if args.study_seeds:
        table = checkpointed(args.work / "study_rows.json", [int(s) for s in args.study_seeds.split(",")],
                             lambda seed: study_numbers(args.work, seed))
        print(f"spread over {len(table)} seeds of test_render_study's configuration")
        for key in STUDY_BOUNDS:
            print(spread_line(key, np.array([r[key] for r in table], float), STUDY_BOUNDS))
        return
    table = checkpointed(args.work / "rows.json", [int(s) for s in args.render_seeds.split(",")],
                         lambda seed: realisation(args.work, seed))
    print(f"spread over {len(table)} render realisations of the seed-0 dataset (verdict consistent in "
          f"{sum(r['fit_consistent'] for r in table):.0f}, model in {sum(r.get('fit_model', 0) for r in table):.0f}); "
          "the tests' bounds:")
    for key in BOUNDS:
        print(spread_line(key, np.array([r[key] for r in table if key in r], float)))
    print("the issues' bars (and the chance one realisation misses each):")
    for key in BARS:
        print(spread_line(key, np.array([r[key] for r in table if key in r], float), BARS))


def checkpointed(path: Path, seeds: list[int], run: Callable[[int], dict[str, float]]) -> list[dict[str, float]]:
    """run(seed) for each seed not yet in the JSON file at path, saved after each: the rows of ``seeds``."""
    rows = json.loads(path.read_text()) if path.exists() else {}
    for seed in seeds:
        if str(seed) not in rows:
            rows[str(seed)] = run(seed)
            atomic_write_text(path, json.dumps(rows, indent=1))
        print(f"seed {seed}: " + ", ".join(f"{k} {v:.3g}" for k, v in rows[str(seed)].items()), flush=True)
    return [rows[str(seed)] for seed in seeds]


if __name__ == "__main__":
    main()

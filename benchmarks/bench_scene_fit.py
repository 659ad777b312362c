"""Benchmark: the scene fit on datasets made from a scene other than the nominal one (issue 25).

For each case a draft dataset is made from a perturbed copy of cornell_cd (the period 5 %
longer, the CD tilted 2 deg more, the light moved 3 cm, or unperturbed for seeds 0-5 with
``--seeds``) and run through ``workbench verify`` against the nominal scene, as a user
would: calibration, the render of each photo's calibrated scene, the scene fit (which takes
the forward model's offsets measured on those renders off the photos'), the fitted scene's
re-render after the verdict ``model``, and the report. Printed per case: the fitted period's,
tilt's and light centre's errors against the truth, the verdict and the parameters it names,
the band-edge residuals after the fit, the photo-vs-render fringe offsets (median, p95) with
the file's scene and after the re-render, and the fit stage's time as a ratio to the
reference workload (benchmarks/reference_speed.py) beside the 60 s bar, with the re-render's
time beside it. Over unperturbed seeds, the RMS of the normalised errors (fitted - truth) /
std, which should lie in 0.5-2. Datasets and runs are kept in ``--work`` (default: a
temporary folder) so a second run reuses them.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
from pathlib import Path

import numpy as np

from benchmarks.reference_speed import SpeedBar, reference_seconds

SPEED_BAR = SpeedBar("the scene fit (verify's fit stage, draft dataset, two photos)", 60.0)
BARS = {"period_error_rel": 0.003, "tilt_error_deg": 0.2, "light_error_mm": 5.0}
CASES = {"period+5%": ("period", 1.68), "tilt+2deg": ("tilt", 22.0), "light+3cm": ("light", 0.308)}


def perturbed_scene(kind: str, value: float, folder: Path) -> Path:
    """A copy of cornell_cd (and its structure, for a period) with one thing changed."""
    from importlib import resources

    scene = resources.files("renderer.scenes").joinpath("cornell_cd.toml").read_text()
    folder.mkdir(parents=True, exist_ok=True)
    if kind == "period":
        structure = resources.files("rcwa.structures").joinpath("cd.toml").read_text()
        (folder / "cd_perturbed.toml").write_text(structure.replace("period = [1.6]", f"period = [{value}]"))
        scene = scene.replace('structure = "cd"', 'structure = "cd_perturbed.toml"')
    elif kind == "tilt":
        t = math.radians(value)
        scene = scene.replace("normal = [0.0, 0.9397, -0.3420]", f"normal = [0.0, {math.cos(t):.6f}, {-math.sin(t):.6f}]")
    elif kind == "light":
        scene = scene.replace("[light]\n", f"[light]\ncenter = [{value}, 0.5487, 0.2795]\n")
    path = folder / f"cornell_cd_{kind}.toml"
    path.write_text(scene)
    return path


def dataset(truth_scene: str, seed: int, work: Path) -> Path:
    """synth (kept in ``work``)."""
    from datasets_synthetic.synth import synth

    folder = work / f"{Path(truth_scene).stem}-seed{seed}" / "dataset"
    if not (folder / "truth.json").exists():
        synth(truth_scene, folder, seed=seed, progress=False)
    return folder


def _offsets(run: Path, photo: str, nominal: bool) -> dict | None:
    """A report's photo-vs-render fringe offsets: the fitted scene's after a re-render, or the file's."""
    path = run / "report" / photo / ("nominal" if nominal else "") / "report.json"
    return json.loads(path.read_text())["fringe_offset_px"] if path.is_file() else None


def run_case(label: str, truth_scene: str, seed: int, work: Path, reference_s: float) -> dict:
    from reports.scene_fit.study import fit_errors, truth_values
    from workbench.verify import VerifySettings, verify

    folder = dataset(truth_scene, seed, work)
    run = work / f"verify-{label}-seed{seed}"
    record = verify(folder, "cornell_cd", run, VerifySettings(progress=False))
    fit = json.loads((run / "fit" / "scene_fit.json").read_text())
    errors = fit_errors(fit, truth_values(truth_scene))
    named = [p["component"] for p in fit["verdict"].get("parameters", [])]
    print(f"{label} seed {seed}: verdict {fit['verdict']['verdict']} {named}; "
          + ", ".join(f"{k} {v:.4g}" + (f" (bar {BARS[k]:g})" if k in BARS else "") for k, v in errors.items())
          + f"; residual median after {fit['verdict']['residuals_after_px']['median']:.2f} px")
    stages = record["stages"]
    rerendered = bool(stages["rerender"].get("result", {}).get("renders"))
    for photo in sorted(p.stem for p in (folder / "photos").iterdir()):
        before, after = _offsets(run, photo, rerendered), _offsets(run, photo, False) if rerendered else None
        print(f"  {photo}: photo-render fringe offsets, the file's scene "
              + (f"median {before['median']:.2f} / p95 {before['p95']:.2f} px ({before['count']} edges)" if before else "-")
              + ("" if after is None else f"; the fitted scene's re-render median {after['median']:.2f} / p95 "
                                         f"{after['p95']:.2f} px ({after['count']} edges) (bar: median under 0.3 px)"))
    print("  " + SPEED_BAR.judge(stages["fit"]["seconds"], reference_s)
          + (f"; the re-render {stages['rerender']['seconds']:.1f} s" if rerendered else ""))
    return fit


def normalised_errors(records: list[dict]) -> np.ndarray:
    """(fitted - nominal) / std of every component of unperturbed fits (the nominal is the truth there)."""
    out = []
    for r in records:
        std = np.concatenate([np.atleast_1d(p["std"]) for p in r["parameters"].values()])
        out.append((np.array(r["values"]) - np.array(r["nominal_values"])) / std)
    return np.concatenate(out)


def main() -> None:
    parser = argparse.ArgumentParser(description="scene fit: accuracy against perturbed truths, and its time")
    parser.add_argument("--work", type=Path, default=None, help="folder for the datasets (kept; default: temporary)")
    parser.add_argument("--seeds", type=int, default=0, help="also fit unperturbed datasets of seeds 0..N-1")
    args = parser.parse_args()
    reference_s = reference_seconds()
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        for label, (kind, value) in CASES.items():
            run_case(label, str(perturbed_scene(kind, value, work / "scenes")), 0, work, reference_s)
        unperturbed = [run_case("unperturbed", "cornell_cd", seed, work, reference_s) for seed in range(args.seeds)]
        if unperturbed:
            z = normalised_errors(unperturbed)
            verdicts = [r["verdict"]["verdict"] for r in unperturbed]
            print(f"unperturbed seeds 0-{args.seeds - 1}: verdicts {verdicts}; normalised errors RMS "
                  f"{float(np.sqrt(np.mean(z**2))):.2f} (bar 0.5-2), max |z| {float(np.max(np.abs(z))):.2f} (bar 3)")


if __name__ == "__main__":
    main()

"""Benchmark: where users wait on verify (issue 28, items 4 and 5), with the report's figures beside each time.

Parts (``--only`` picks some; default all), each a fresh ``workbench verify`` run (its folder
cleared first, so no stage is skipped; the efficiency tables come from the user's cache, built
once), run with the fixed render (today's spp: draft 256, paper 2045) and with verify's default,
the targeted render (renderer.render_target):

* ``demo``: ``make demo``'s main job, the seed-0 draft dataset's synth (timed when it is made) and
  its verify of the first photo; bar: under 3 minutes on the 2-core machine (issue 28);
* ``draft``: the draft verify of the same dataset's two photos;
* ``paper``: the paper preset's verify of a dataset of ONE 978 x 734 photo (view0 of ``synth --preset
  full``, about 14 minutes to make once, with its bracket and board views); bar: under 6 minutes,
  fringe offsets (median, p95) no worse than the fixed 2045-spp render's (issue 28). Tens of
  minutes in all;
* ``cluster``: the draft verify of both photos (targeted) on a LocalCluster of 2 worker processes
  against 1 (``--workers``); the time ratio, which should be under 1, and whether the calibrations
  agree (rotation, centre) and the renders are the same bytes.

Beside each time: each photo's fringe offsets photo - render (median, p95, count, from report.json)
and the calibration's errors against the truth (workbench.score: rotation, centre, FOV, principal
point, exposure, response), the render stage's seconds and the targeted render's spp per region; the
speed bars as ratios to the reference workload (benchmarks/reference_speed.py). The rows go to
WORK/bench_verify.json (merged with earlier runs' rows, by part and label) and WORK/bench_verify.csv.
``--work DIR`` keeps the datasets (and the runs) between runs; default: a temporary folder.

    python -m benchmarks.bench_verify --work out/bench_verify --only draft,cluster
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks.reference_speed import SpeedBar, reference_seconds
from workbench.core.files import atomic_write_text

PARTS = ("demo", "draft", "paper", "cluster")
SCENE, SEED = "cornell_cd", 0
FIXED_SPP = {"draft": 256, "paper": 2045}  # today's fixed render (workbench.verify_run.PRESETS)
BARS = {"demo": SpeedBar("make demo's main job (synth + verify of one photo)", 180.0),
        "paper": SpeedBar("paper-preset verify of one 978 x 734 photo", 360.0)}
SCORE_KEYS = ("rotation_deg", "centre_mm", "fov_deg", "principal_point_pct", "exposure_light_pct", "response_rms_pct")


def dataset(work: Path, preset: str) -> tuple[Path, float | None]:
    """The seed-0 dataset of ``preset`` in WORK (made once), and synth's seconds when made in this run."""
    from datasets_synthetic.synth import synth

    folder = work / f"dataset-{preset}-seed{SEED}"
    if (folder / "truth.json").exists():
        return folder, None
    start = time.perf_counter()
    synth(SCENE, folder, seed=SEED, preset=preset, progress=False, force=True)
    return folder, time.perf_counter() - start


def verify_row(data: Path, out: Path, *, preset: str, spp: int | None, photos: tuple[str, ...] = (),
               workers: int | None = None) -> dict[str, Any]:
    """A fresh verify run into ``out``: its time, stages, fringe offsets, render spp and score."""
    from workbench.score import score_run
    from workbench.verify import VerifySettings, verify

    shutil.rmtree(out, ignore_errors=True)
    start = time.perf_counter()
    record = verify(data, SCENE, out, VerifySettings(preset=preset, spp=spp, photos=photos, workers=workers,
                                                     progress=False))
    seconds = time.perf_counter() - start
    score = score_run(out, data / "truth.json")
    row: dict[str, Any] = {"seconds": round(seconds, 1), "render": "fixed" if spp else "target", "spp": spp,
                           "workers": workers, "stages_s": record["summary"]["seconds_per_stage"]}
    row |= {f"score_{k}": score["calibration"][k] for k in SCORE_KEYS}
    row["photos"] = {}
    for name, p in record["summary"]["photos"].items():
        sidecar = json.loads((out / "render" / f"{Path(name).stem}.json").read_text())
        target = sidecar.get("target") or {}
        row["photos"][name] = {"fringe_offset_px": p["fringe_offset_px"], "render_sha256": sidecar["output_sha256"],
                               "frame_spp": target.get("frame_spp", sidecar["spp"]),
                               "cd_spp": (target.get("regions", {}).get("cd") or {}).get("spp")}
    return row


def _fixed_and_target(part: str, data: Path, work: Path, preset: str, photos: tuple[str, ...]) -> list[dict]:
    rows = []
    for label, spp in (("fixed", FIXED_SPP[preset]), ("target", None)):
        row = verify_row(data, work / "runs" / f"{part}-{label}", preset=preset, spp=spp, photos=photos)
        rows.append({"part": part, "label": label} | row)
    return rows


def part_demo(work: Path) -> list[dict]:
    data, synth_s = dataset(work, "draft")
    rows = _fixed_and_target("demo", data, work, "draft", ("view0.dng",))
    for row in rows:  # the main job: synth (when made in this run) + verify
        row["synth_s"] = None if synth_s is None else round(synth_s, 1)
        row["main_job_s"] = None if synth_s is None else round(synth_s + row["seconds"], 1)
    return rows


def part_draft(work: Path) -> list[dict]:
    return _fixed_and_target("draft", dataset(work, "draft")[0], work, "draft", ())


def one_photo(data: Path, photo: str) -> Path:
    """A copy of ``data`` whose photos/ holds ``photo`` alone (its brackets, board views and truth kept), in WORK:
    a one-photo dataset, so that its verify calibrates one pose too."""
    folder = data.with_name(f"{data.name}-{Path(photo).stem}")
    if not (folder / "truth.json").exists():
        shutil.rmtree(folder, ignore_errors=True)
        shutil.copytree(data, folder, ignore=lambda where, names: [n for n in names if Path(where).name == "photos"
                                                                    and n != photo])
    return folder


def part_paper(work: Path) -> list[dict]:
    return _fixed_and_target("paper", one_photo(dataset(work, "full")[0], "view0.dng"), work, "paper", ())


def part_cluster(work: Path) -> list[dict]:
    from workbench.score import centre_error_mm, rotation_error_deg

    data = dataset(work, "draft")[0]
    rows = [{"part": "cluster", "label": f"{n}-worker"} | verify_row(data, work / "runs" / f"cluster-{n}", preset="draft",
                                                                     spp=None, workers=n) for n in (1, 2)]
    one, two = (json.loads((work / "runs" / f"cluster-{n}" / "calibration" / "calibration.json").read_text())
                for n in (1, 2))
    poses = one["camera"]["world_to_camera"]
    import numpy as np

    rows[1]["ratio_to_1_worker"] = round(rows[1]["seconds"] / rows[0]["seconds"], 3)
    rows[1]["calibration_rotation_diff_deg"] = max(
        rotation_error_deg(np.array(poses[p]), np.array(two["camera"]["world_to_camera"][p])) for p in poses)
    rows[1]["calibration_centre_diff_mm"] = max(
        centre_error_mm(np.array(poses[p]), np.array(two["camera"]["world_to_camera"][p])) for p in poses)
    rows[1]["same_render_bytes"] = all(rows[0]["photos"][p]["render_sha256"] == rows[1]["photos"][p]["render_sha256"]
                                       for p in rows[0]["photos"])
    return rows


def describe(row: dict, reference_s: float) -> list[str]:
    """The row as printed: time, stages, score, each photo's fringe offsets and spp; a bar where it has one."""
    stages = ", ".join(f"{k} {v:.0f}" for k, v in row["stages_s"].items())
    score = ", ".join(f"{k.removeprefix('score_')} {row[k]:.3g}" for k in (f"score_{k}" for k in SCORE_KEYS)
                      if row.get(k) is not None)
    lines = [f"{row['part']} {row['label']}: {row['seconds']:.1f} s (stages s: {stages}); score: {score}"]
    for name, p in row["photos"].items():
        fo = p["fringe_offset_px"] or {}
        offsets = (f"median {fo['median']:.3f} px, p95 {fo['p95']:.3f} px ({fo.get('count')} edges)"
                   if fo.get("median") is not None else "no band edge in both")
        lines.append(f"  {name}: fringe offsets {offsets}; frame {p['frame_spp']} spp, CD {p['cd_spp']}")
    if row["part"] == "demo" and row.get("main_job_s") is not None:
        lines.append(f"  synth {row['synth_s']:.1f} s; " + BARS["demo"].judge(row["main_job_s"], reference_s))
    if row["part"] == "paper":
        lines.append("  " + BARS["paper"].judge(row["seconds"], reference_s))
    if "ratio_to_1_worker" in row:
        lines.append(f"  2 workers / 1 worker: {row['ratio_to_1_worker']:.3f} (bar: under 1); calibrations apart by "
                     f"{row['calibration_rotation_diff_deg']:.2g} deg, {row['calibration_centre_diff_mm']:.2g} mm; "
                     f"renders the same bytes: {row['same_render_bytes']}")
    return lines


def _offsets(row: dict, key: str) -> list[float | None]:
    return [(p["fringe_offset_px"] or {}).get(key) for p in row["photos"].values()]


def compare(rows: list[dict]) -> list[str]:
    """The targeted render against the fixed one per part: time, and the fringe offsets' median and p95 per photo
    (issue 28: the paper preset's no worse than the fixed 2045-spp render's)."""
    lines = []
    by = {(r["part"], r["label"]): r for r in rows}
    for part in ("demo", "draft", "paper"):
        fixed, target = by.get((part, "fixed")), by.get((part, "target"))
        if fixed is None or target is None:
            continue
        pairs = [(a, b) for key in ("median", "p95") for a, b in zip(_offsets(target, key), _offsets(fixed, key),
                                                                     strict=True)]
        worse = any(a is None or (b is not None and a > b) for a, b in pairs)
        lines.append(f"{part}: the targeted verify takes {target['seconds'] / fixed['seconds']:.2f} of the fixed one's time; "
                     f"fringe offsets median/p95 per photo, fixed {_offsets(fixed, 'median')}/{_offsets(fixed, 'p95')} px, "
                     f"targeted {_offsets(target, 'median')}/{_offsets(target, 'p95')} px"
                     + (f": {'worse than' if worse else 'no worse than'} the fixed render's" if part == "paper" else ""))
    return lines


def save(work: Path, rows: list[dict]) -> None:
    """WORK/bench_verify.json (this run's rows over earlier ones of the same part and label) and the CSV."""
    path = work / "bench_verify.json"
    old = json.loads(path.read_text()) if path.is_file() else []
    keys = {(r["part"], r["label"]) for r in rows}
    merged = [r for r in old if (r["part"], r["label"]) not in keys] + rows
    atomic_write_text(path, json.dumps(merged, indent=2, default=float) + "\n")
    flat = []
    for r in merged:
        for name, p in r["photos"].items():
            fo = p["fringe_offset_px"] or {}
            flat.append({k: v for k, v in r.items() if k not in ("photos", "stages_s")}
                        | {"photo": name, "fringe_median_px": fo.get("median"), "fringe_p95_px": fo.get("p95"),
                           "frame_spp": p["frame_spp"], "cd_spp": p["cd_spp"]})
    columns = list(dict.fromkeys(k for row in flat for k in row))
    with open(work / "bench_verify.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(flat)


def main() -> None:
    parser = argparse.ArgumentParser(description="verify's waits: demo, draft, paper (fixed vs targeted), cluster")
    parser.add_argument("--only", default=",".join(PARTS), help=f"parts to run, comma-separated (default: {','.join(PARTS)})")
    parser.add_argument("--work", type=Path, default=None, help="folder for datasets, runs and results (kept)")
    args = parser.parse_args()
    parts = [p.strip() for p in args.only.split(",") if p.strip()]
    unknown = sorted(set(parts) - set(PARTS))
    if unknown:
        parser.error(f"--only: unknown part(s) {', '.join(unknown)}; expected some of {', '.join(PARTS)}")
    reference_s = reference_seconds()
    print(f"reference workload: {reference_s:.3f} s")
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        rows: list[dict] = []
        for part in parts:
            new = globals()[f"part_{part}"](work)
            rows += new
            save(work, rows)
            for row in new:
                print("\n".join(describe(row, reference_s)), flush=True)
        print("\n".join(compare(rows)))
        print(f"rows: {work / 'bench_verify.json'}, {work / 'bench_verify.csv'}")


if __name__ == "__main__":
    main()

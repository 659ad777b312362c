"""``workbench study fit``: the scene fit's accuracy against its time.

One dataset whose photos were made from a known scene (``--truth-scene``: the scene file
synth was given, which may differ from the nominal ``--scene``) is fitted again and again:

* over the forward model's resolution: sub-rays per pixel axis and the wavelength step
  (``RESOLUTIONS``);
* over the share of the photos' band edges used (``EDGE_FRACTIONS``, at the default
  resolution);
* over the number of photos (the first photo alone, then all);
* with ``--renders``: without the forward model's offsets measured on them (reports.scene_fit.bias).

Each fit's errors against the truth scene: the period's (relative), the tilt's (the angle
between the fitted and the true normal, degrees), the light centre's (mm), with the fit's
seconds and its standard deviations. Writes DIR/study_fit.json, study_fit.csv and
study_fit.png/.svg (error against seconds, one curve per swept setting).
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from rcwa.structure import load_structure
from renderer.scene import load_scene
from reports.scene_fit.apply import tilt_angle_deg
from reports.scene_fit.fit import FitSettings
from reports.scene_fit.job import FitInputs, run_fit
from reports.scene_fit.verdict_record import Verdict
from workbench.core.files import atomic_write_csv, atomic_write_text
from workbench.core.plots import new_figure, save_figure
from workbench.core.version import versions

RESOLUTIONS = ((1, 10.0), (1, 5.0), (2, 5.0))  # (supersample, wavelength step nm); the fit's default is (1, 5)
EDGE_FRACTIONS = (0.25, 0.5)  # besides 1.0 (the default resolution's run)


def truth_values(truth_scene: str) -> dict[str, Any]:
    """The true period (um), CD normal and light centre of the scene the photos were made from."""
    spec = load_scene(truth_scene)
    cd = spec.cds[0]
    return {"period_um": float(load_structure(cd.structure).period[0]), "normal": list(cd.normal),
            "light_center": list(spec.light.center)}


def fit_errors(record: dict[str, Any], truth: dict[str, Any]) -> dict[str, Any]:
    """The fitted parameters' errors against the truth (those the fit freed)."""
    p = record["parameters"]
    out: dict[str, Any] = {}
    if "cd[0].structure.period" in p:
        out["period_error_rel"] = p["cd[0].structure.period"]["value"] / truth["period_um"] - 1.0
        out["period_std_rel"] = p["cd[0].structure.period"]["std"] / truth["period_um"]
    if "cd[0].normal" in p:
        out["tilt_error_deg"] = tilt_angle_deg(np.asarray(p["cd[0].normal"]["value"]), np.asarray(truth["normal"]))
        out["tilt_std_deg"] = p["cd[0].normal"]["tilt_std_deg"]
    if "light.center" in p:
        out["light_error_mm"] = 1e3 * float(np.linalg.norm(np.asarray(p["light.center"]["value"])
                                                           - np.asarray(truth["light_center"])))
    return out


def _runs(photos: list[str], renders: Path | None) -> list[tuple[str, dict[str, Any]]]:
    """(swept setting, FitInputs changes) for every fit of the study."""
    runs: list[tuple[str, dict[str, Any]]] = [("resolution", {"supersample": s, "step_nm": step}) for s, step in RESOLUTIONS]
    runs += [("edges", {"edge_fraction": f}) for f in EDGE_FRACTIONS]
    if len(photos) > 1:
        runs.append(("photos", {"photos": (photos[0],)}))
    if renders is not None:
        runs.append(("bias", {"renders": None}))  # the same fit without the forward model's measured offsets
    return runs


def run_fit_study(dataset: Path, scene: str, calibration: Path, truth_scene: str, out: Path,
                  progress: bool = True, renders: Path | None = None) -> dict[str, Any]:
    """Every fit of the study (module docstring); returns study_fit.json's content."""
    started = time.perf_counter()
    truth = truth_values(truth_scene)
    photos = sorted(p.name for p in (dataset / "photos").iterdir() if p.is_file())
    rows = []
    runs = _runs(photos, renders)
    for i, (sweep, change) in enumerate(runs):
        settings = FitSettings(edge_fraction=change.get("edge_fraction", 1.0))
        inputs = FitInputs(dataset, scene, calibration, out / f"fit{i:02d}", change.get("photos", ()),
                           change.get("supersample", 1), change.get("step_nm", 5.0), settings,
                           change.get("renders", renders))
        record = run_fit(inputs)
        judged = Verdict.from_json(record["verdict"], inputs.out / "scene_fit.json")
        row = {"sweep": sweep, "supersample": inputs.supersample, "step_nm": inputs.step_nm,
               "edge_fraction": settings.edge_fraction, "photos": len(record["photos"]),
               "render_offsets": inputs.renders is not None,
               "edges": judged.residuals_after_px.count, "seconds": record["timings"]["total"],
               "verdict": judged.outcome.value, **fit_errors(record, truth)}
        rows.append(row)
        if progress:
            print(f"study fit {i + 1}/{len(runs)}: {sweep} {change}: {row['seconds']:.0f} s, "
                  + ", ".join(f"{k} {v:.4g}" for k, v in row.items() if k.endswith(("_rel", "_deg", "_mm"))))
    data = {"dataset": str(dataset), "scene": scene, "truth_scene": truth_scene, "truth": truth, "rows": rows,
            "versions": versions("numpy", "scipy", "nlopt"), "timings": {"total_s": time.perf_counter() - started}}
    atomic_write_text(out / "study_fit.json", json.dumps(data, indent=2) + "\n")
    atomic_write_csv(out / "study_fit.csv", rows)
    _plot(rows, out)
    return data


def _plot(rows: list[dict[str, Any]], out: Path) -> None:
    fig, axes = new_figure()
    for sweep in dict.fromkeys(r["sweep"] for r in rows):
        chosen = sorted((r for r in rows if r["sweep"] == sweep), key=lambda r: r["seconds"])
        seconds = [r["seconds"] for r in chosen]
        axes[0].plot(seconds, [100 * abs(r.get("period_error_rel", np.nan)) for r in chosen], "o-", label=sweep)
        axes[1].plot(seconds, [r.get("tilt_error_deg", np.nan) for r in chosen], "o-", label=sweep)
    axes[0].set(xlabel="fit time (s)", ylabel="|period error| (%)", title="period")
    axes[1].set(xlabel="fit time (s)", ylabel="tilt error (deg)", title="CD tilt")
    save_figure(fig, axes, out, "study_fit")


"""`workbench study render cornell_cd` on a tiny configuration: the files hold the study, trends with reasons.

Asserted:
* the files hold what the study returned: study_render.json equals it, each CSV holds its
  rows (to CSV's text round trip), the plots are a PNG and an SVG; the JSON records the
  settings, the versions that produced it and its time (house rule: outputs record
  settings, versions, timings);
* the improved mode's error falls as spp grows (Monte Carlo converges), and improved
  mode has the lower error at the largest spp (measured 0.64 against paper's 1.68 at 128
  spp; fixed seeds, so the same numbers every run);
* the furnace energy of improved mode is within TOLERANCE_ENERGY of 1 (a lossless
  grating, tests/renderer/test_bwdf_energy.py), and paper mode's stays within
  PAPER_ENERGY_BAND (its pbrt-v3 weight carries cos(theta_i)/cos(theta_o), which does not
  conserve energy: the +2.7 % test_bwdf_energy's docstring notes for grazing views);
* paper mode's colour shift grows from the smallest to the largest Delta (a wider Delta
  admits wavelengths at the wrong implied order).

Noise allowed (issue 23): the study's seeds are fixed, but each bound is set against the
spread over other seeds (RenderStudyConfig.seed; `python -m benchmarks.bench_realisations
--work DIR --study-seeds 0,...,11`), so that the pass does not rest on the draw. Measured
over 12 seeds: improved's error at 128 spp over 8 spp 0.25 +- 0.09 (< 1 at 8 SD), improved
over paper at 128 spp 0.44 +- 0.08 (7 SD). Before, at Delta 0.02 and 0.4 and 128 spp the
shift ratio was 0.79 +- 0.10 (range 0.63-0.99: 3 % of seeds fail), the noise of the small
Delta's shift hiding the effect; at 0.02 and 0.5 and 512 spp it is 0.45-0.49 (4 seeds). Paper
mode's furnace weight has a heavy tail (P(W > w) ~ 8e-3 w^-1.2, measured over 2e6 samples:
infinite variance), so its plain mean ranged 0.99-1.25 over 40 seeds of 50,000 samples and
its band is judged on the median of 20 block means (renderer.render_study.median_of_means):
1.0257 +- 0.0033 over 20 seeds of 2,000,000 samples (band at 22 SD); improved's plain mean
there 0.99723 +- 0.00032 (TOLERANCE_ENERGY at 22 SD; 0.99701 +- 0.00086 at 500,000).
"""

import csv
import dataclasses
import json

import pytest

from renderer.render_study import RenderStudyConfig, run_render_study

TOLERANCE_ENERGY = 0.01  # 2,000,000 furnace samples: 0.99723 +- 0.00032 over 20 seeds (22 SD)
PAPER_ENERGY_BAND = (0.95, 1.1)  # its median of means 1.0257 +- 0.0033; a broken weight (lost N_tot, 4 or 2) lands far out
CSV_REL = 1e-12  # CSV writes Python's repr of each float, which reads back exactly; allow round-off only


def _csv_rows(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _same(text: str, value) -> bool:
    if isinstance(value, str):
        return text == value
    return float(text) == pytest.approx(float(value), rel=CSV_REL)


def test_render_study_outputs(mitsuba_variant, tmp_path):
    cfg = RenderStudyConfig(resolution=(160, 120), spp_steps=(8, 128), reference_spp=512, deltas=(0.02, 0.5),
                            delta_spp=512, furnace_samples=2_000_000)
    out = tmp_path / "out"
    data = run_render_study("cornell_cd", out, cfg, progress=False)
    assert data["element_pixels"] > 100

    assert json.loads((out / "study_render.json").read_text()) == json.loads(json.dumps(data))
    assert data["config"] == dataclasses.asdict(cfg) and data["scene"] == "cornell_cd"
    assert {"workbench", "mitsuba", "drjit"} <= set(data["versions"]) and data["timings"]["total_s"] > 0
    for name, key in (("render_error_vs_time", "error_vs_time"), ("render_delta_bias", "delta_bias"),
                      ("render_energy", "energy")):
        rows = _csv_rows(out / f"{name}.csv")
        assert len(rows) == len(data[key]) and set(rows[0]) == set(data[key][0]), name
        assert all(_same(r[k], d[k]) for r, d in zip(rows, data[key], strict=True) for k in d), name
    assert (out / "study_render.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "<svg" in (out / "study_render.svg").read_text()[:1000]

    assert [(r["mode"], r["spp"]) for r in data["error_vs_time"]] == [(m, s) for m in ("paper", "improved")
                                                                       for s in cfg.spp_steps]
    errors = {(r["mode"], r["spp"]): r["relative_rms_error"] for r in data["error_vs_time"]}
    assert errors["improved", cfg.spp_steps[-1]] < errors["improved", cfg.spp_steps[0]]
    assert errors["improved", cfg.spp_steps[-1]] < errors["paper", cfg.spp_steps[-1]]
    assert all(r["seconds"] > 0 for r in data["error_vs_time"])

    energy = {e["mode"]: e for e in data["energy"]}
    assert abs(energy["improved"]["energy"] - 1) < TOLERANCE_ENERGY, energy
    assert PAPER_ENERGY_BAND[0] < energy["paper"]["energy_median_of_means"] < PAPER_ENERGY_BAND[1], energy
    shifts = [b["chromaticity_shift"] for b in data["delta_bias"]]
    assert [b["delta"] for b in data["delta_bias"]] == list(cfg.deltas)
    assert shifts[-1] > shifts[0]

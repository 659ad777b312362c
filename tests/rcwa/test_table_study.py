"""`workbench study rcwa` (rcwa/table_study.py): what its files hold and whether its curves and
recommendations are right.

The study runs once on the CD at a small configuration (seconds). Asserted, each with its
reason and named tolerance:

* the files: JSON, CSV (columns named with their units, rows equal to the JSON's), PNG
  and SVG;
* truncation: Li's rule converges -- the error of the kept orders falls with every
  doubling of the harmonics while it stands above NOISE_FLOOR, and ends below it -- and
  converges far faster than the Laurent rule on the CD's aluminium (Li 1996);
* interpolation: bilinear interpolation is second order, error ~ h^2, where the
  efficiencies are smooth: checked on a subwavelength lossy grating (only order 0
  propagates at any angle, so no Rayleigh-anomaly kink), whose fitted order must lie
  within ORDER_TOLERANCE of 2; on the CD the kinks of orders appearing and vanishing
  keep it near first order, so there it is only asked to fall;
* recommendations: each reachable target's settings meet it when measured again
  independently (a 321-harmonic reference instead of the study's 161, fresh random
  directions), and are the cheapest measured settings that meet half the target each.
"""

from __future__ import annotations

import csv
import dataclasses
import json

import numpy as np
import pytest

import rcwa
from rcwa.table_study import StudyConfig, interpolation_study, run_study, truncation_study
from tests.rcwa.helpers import nk, structure

# On the CD at these directions the 161-harmonic reference itself is 2.4e-4 from a
# 321-harmonic solve (measured); a row within a few times that measures the reference's
# error as much as its own, so monotone decrease is asked for only above 1e-3.
NOISE_FLOOR = 1e-3
# Li's error from 21 to 81 harmonics: measured 0.0166 -> 3.6e-4 (x46); asked: x10.
MIN_TRUNCATION_GAIN = 10.0
# Laurent / Li error at 41 harmonics on the CD: measured 20 (0.031 against 0.0015).
MIN_RULE_RATIO = 5.0
# Fitted order of the RMS (and max) interpolation error over steps 15, 7.5, 3.75 deg at
# 200 random directions: measured 1.91-2.05 over seeds 0-4; the estimate's spread comes
# from the random test directions, 0.3 covers it with margin and still rejects order 1.
ORDER_TOLERANCE = 0.3
CHECK_REFERENCE_ORDERS = 321

CD_CONFIG = StudyConfig(wavelengths_nm=(550.0,), directions_deg=((20.0, 30.0), (50.0, 10.0)), orders=(11, 21, 41, 81),
                        reference_orders=161, interpolation_orders=21, steps_deg=(15.0, 7.5), test_points=40,
                        targets=(0.04, 0.02, 1e-3))
COLUMNS = {
    "truncation": {"rule", "orders", "max_error", "seconds_per_solve"},
    "interpolation": {"grid", "step_deg", "points", "max_error", "rms_error", "table_seconds", "table_bytes"},
    "presets": {"target_error", "reachable", "orders", "grid", "step_deg", "estimated_table_seconds", "table_bytes"},
}


@pytest.fixture(scope="module")
def cd_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    return out, run_study(rcwa.load_structure("cd"), out, CD_CONFIG, progress=False)


def _read_csv(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _same_row(text_row: dict, row: dict) -> bool:
    def parse(text: str, like):
        return {bool: lambda t: t == "True", int: int, float: float, str: str}[type(like)](text)

    return all(parse(text_row[k], v) == v for k, v in row.items()) and all(
        text_row[k] == "" for k in text_row if k not in row)


def test_files_hold_the_study(cd_study):
    out, data = cd_study
    s = rcwa.load_structure("cd")
    assert json.loads((out / "study_rcwa.json").read_text()) == json.loads(json.dumps(data))
    assert data["structure"] == "cd" and data["run"]["structure_sha256"] == s.content_hash and data["run"]["seconds"] > 0
    assert data["config"] == dataclasses.asdict(CD_CONFIG)
    for name, columns in COLUMNS.items():
        rows = _read_csv(out / f"{name}.csv")
        assert set(rows[0]) == columns, name  # units are in the names: _deg, _seconds, _bytes
        assert len(rows) == len(data[name]) and all(_same_row(t, r) for t, r in zip(rows, data[name], strict=True))
    assert (out / "study_rcwa.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "<svg" in (out / "study_rcwa.svg").read_text()[:1000]


def test_truncation_error_falls_with_harmonics(cd_study):
    _, data = cd_study
    rows = {(r["rule"], r["orders"]): r["max_error"] for r in data["truncation"]}
    assert set(rows) == {(rule, n) for rule in ("li", "laurent") for n in CD_CONFIG.orders}
    li = [rows["li", n] for n in CD_CONFIG.orders]
    above = [e for e in li if e > NOISE_FLOOR]
    assert above == sorted(above, reverse=True) and len(set(above)) == len(above), li
    assert li[-1] < NOISE_FLOOR, li
    assert rows["li", 21] / rows["li", 81] > MIN_TRUNCATION_GAIN, li
    assert rows["laurent", 41] / rows["li", 41] > MIN_RULE_RATIO
    assert all(r["seconds_per_solve"] > 0 for r in data["truncation"])


def test_interpolation_table_sizes_are_float32_per_kept_order(cd_study):
    _, data = cd_study
    for r in data["interpolation"]:
        if r["grid"] == "theta-phi":  # 0..90 deg in theta (the last row at 89.999) and in phi
            assert r["points"] == (90 / r["step_deg"] + 1) ** 2
        assert r["table_bytes"] == r["points"] * CD_CONFIG.table_wavelengths * CD_CONFIG.keep * 4


def test_interpolation_error_falls_on_the_cd(cd_study):
    _, data = cd_study
    for grid in ("theta-phi", "direction-cosines"):
        rms = [r["rms_error"] for r in data["interpolation"] if r["grid"] == grid]
        assert rms[-1] < rms[0], grid


def test_bilinear_interpolation_is_second_order_where_smooth():
    # Period 0.2 um at 550 nm: |kx0 +- lambda/Lambda| >= 2.75 - 1 > n_superstrate, so only
    # order 0 propagates at every angle; the metal substrate makes R_0 vary with angle.
    smooth = structure([0.2], nk(1.0), nk(0.5, 3.0), [{"thickness": 0.05, "material": nk(1.0),
                       "shapes": [{"material": nk(0.5, 3.0), "x": [0.0, 0.1]}]}])
    cfg = StudyConfig(wavelengths_nm=(550.0,), interpolation_orders=11, keep=3, steps_deg=(15.0, 7.5, 3.75), test_points=200)
    rows = interpolation_study(smooth, cfg)
    by_grid = {g: [r for r in rows if r["grid"] == g] for g in ("theta-phi", "direction-cosines")}
    steps = np.log([r["step_deg"] for r in by_grid["theta-phi"]])
    for measure in ("rms_error", "max_error"):
        order = np.polyfit(steps, np.log([r[measure] for r in by_grid["theta-phi"]]), 1)[0]
        assert abs(order - 2.0) < ORDER_TOLERANCE, (measure, order)
    # In direction cosines R(u) has cos(theta) = sqrt(1 - u^2), whose slope is infinite at
    # the rim, so the same number of points interpolates worse: why tables use (theta, phi).
    for tp, dc in zip(by_grid["theta-phi"], by_grid["direction-cosines"], strict=True):
        assert tp["points"] == dc["points"] and tp["rms_error"] < dc["rms_error"]


def test_recommended_settings_meet_their_target(cd_study):
    _, data = cd_study
    s = rcwa.load_structure("cd")
    presets = {p["target_error"]: p for p in data["presets"]}
    li = sorted((r for r in data["truncation"] if r["rule"] == "li"), key=lambda r: r["orders"])
    assert [presets[t]["reachable"] for t in CD_CONFIG.targets] == [True, True, False]
    assert all(r["rms_error"] > CD_CONFIG.targets[-1] / 2 for r in data["interpolation"])  # truly out of reach
    reachable = [presets[t] for t in CD_CONFIG.targets[:2]]
    for p in reachable:
        target = p["target_error"]
        assert p["orders"] == next(r["orders"] for r in li if r["max_error"] <= target / 2)  # the fewest that do
        meeting = [r for r in data["interpolation"] if r["rms_error"] <= target / 2]
        chosen = next(r for r in meeting if (r["grid"], r["step_deg"]) == (p["grid"], p["step_deg"]))
        assert chosen["table_seconds"] == min(r["table_seconds"] for r in meeting)
    # Measured again, independently: a better reference and fresh random directions.
    again = dataclasses.replace(CD_CONFIG, orders=tuple(sorted({p["orders"] for p in reachable})),
                                reference_orders=CHECK_REFERENCE_ORDERS,
                                steps_deg=tuple(sorted({p["step_deg"] for p in reachable}, reverse=True)),
                                seed=CD_CONFIG.seed + 1)
    truncation = {r["orders"]: r["max_error"] for r in truncation_study(s, again) if r["rule"] == "li"}
    interpolation = {(r["grid"], r["step_deg"]): r["rms_error"] for r in interpolation_study(s, again)}
    for p in reachable:
        assert truncation[p["orders"]] <= p["target_error"], (p, truncation)
        assert interpolation[p["grid"], p["step_deg"]] <= p["target_error"], (p, interpolation)


def test_a_step_that_does_not_divide_90_covers_the_whole_azimuth_range():
    """A 20 deg grid ends at 80 deg unless 90 is appended; off-grid test points up to 90
    deg must still be interpolated (a regression: scipy refused them as out of bounds)."""
    from rcwa.table_study import StudyConfig, interpolation_study
    from tests.rcwa.helpers import lamellar

    cfg = StudyConfig(wavelengths_nm=(550.0,), interpolation_orders=11, keep=3, steps_deg=(20.0,), test_points=50)
    (row_tp, row_dc) = interpolation_study(lamellar(), cfg)
    assert row_tp["max_error"] >= 0 and row_dc["max_error"] >= 0


def test_a_see_through_cells_interpolation_error_is_not_hidden_by_r_plus_t():
    """For a lossless cell where only order 0 propagates R0 + T0 = 1 everywhere, so scoring
    their sum would report no interpolation error; R and T are scored apart."""
    from rcwa.table_study import StudyConfig, interpolation_study
    from tests.rcwa.helpers import lamellar

    sub_wavelength = lamellar(period=0.3, fill=(0.0, 0.15))  # 0.3 um < 550 nm / 1.5: only the zero orders propagate
    cfg = StudyConfig(wavelengths_nm=(550.0,), interpolation_orders=11, keep=3, steps_deg=(15.0,), test_points=50)
    rows = interpolation_study(sub_wavelength, cfg)
    assert all(r["max_error"] > 1e-6 for r in rows)  # Fresnel-like R varies with angle; a sum would give ~1e-16

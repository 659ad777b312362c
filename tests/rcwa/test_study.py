"""`workbench study rcwa`: the files it writes and the trends they must show.

Run on a small configuration (seconds). Asserted with reasons: Li's rule error falls as
harmonics grow (it converges), the Laurent rule is worse than Li's for the CD's aluminium
(Li 1996) at the largest count, and interpolation error falls as the step shrinks.
"""

import json

from rcwa.study import StudyConfig, run_study
import rcwa


def test_study_writes_data_and_plots(tmp_path):
    cfg = StudyConfig(wavelengths_nm=(550.0,), directions_deg=((20.0, 30.0), (50.0, 10.0)), orders=(11, 21, 41),
                      reference_orders=121, interpolation_orders=21, steps_deg=(15.0, 7.5), test_points=40)
    data = run_study(rcwa.load_structure("cd"), tmp_path, cfg)
    for name in ("study_rcwa.json", "truncation.csv", "interpolation.csv", "presets.csv", "study_rcwa.png", "study_rcwa.svg"):
        assert (tmp_path / name).stat().st_size > 0
    assert json.loads((tmp_path / "study_rcwa.json").read_text())["structure"] == "cd"
    li = [r["max_error"] for r in data["truncation"] if r["rule"] == "li"]
    laurent = [r["max_error"] for r in data["truncation"] if r["rule"] == "laurent"]
    assert li[-1] < li[0] and laurent[-1] > li[-1]
    for grid in ("theta-phi", "direction-cosines"):
        rms = [r["rms_error"] for r in data["interpolation"] if r["grid"] == grid]
        assert rms[-1] < rms[0]
    assert all(r["seconds_per_solve"] > 0 for r in data["truncation"])

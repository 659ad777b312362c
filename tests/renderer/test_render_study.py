"""`workbench study render cornell_cd` on a tiny configuration: files written, trends with reasons.

Asserted: the improved mode's error falls as spp grows (Monte Carlo converges), the
furnace energy of improved mode is within 1 % (tests/renderer/test_bwdf_energy.py), and
paper mode's colour shift grows from the smallest to the largest Delta (a wider Delta
admits wavelengths at the wrong implied order).
"""

from renderer.study import RenderStudyConfig, run_render_study


def test_render_study_outputs(mitsuba_variant, tmp_path):
    cfg = RenderStudyConfig(resolution=(160, 120), spp_steps=(8, 128), reference_spp=512, deltas=(0.02, 0.4),
                            delta_spp=128, furnace_samples=50_000)
    data = run_render_study("cornell_cd", tmp_path / "out", cfg)
    assert data["element_pixels"] > 100
    for name in ("study_render.json", "render_error_vs_time.csv", "render_delta_bias.csv", "render_energy.csv",
                 "study_render.png", "study_render.svg"):
        assert (tmp_path / "out" / name).stat().st_size > 0
    improved = [r["relative_rms_error"] for r in data["error_vs_time"] if r["mode"] == "improved"]
    assert improved[-1] < improved[0]
    energy = {e["mode"]: e["energy"] for e in data["energy"]}
    assert abs(energy["improved"] - 1) < 0.01
    shifts = [b["chromaticity_shift"] for b in data["delta_bias"]]
    assert shifts[-1] > shifts[0]

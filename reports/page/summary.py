"""The report page's summary block (first after the verdict) and its table of the fitted camera.

Numbers go through reports.page.html (format_number, format_value: to their precision, never a
repr; every text escaped).
"""

from __future__ import annotations

from typing import Any

from renderer.lens import LENS_MODELS
from reports.page import html as page

CALIBRATION_ROWS = (("fx", "px", "fx"), ("fy", "px", "fy"), ("cx", "px", "cx"), ("cy", "px", "cy"),
                    ("fov_x_deg", "deg", None), ("position_m", "m", "translation_m"))


SUMMARY_TIPS = {
    "photo vs render band edges": "each band edge of the photo (a half-maximum crossing along the CD's polar grids) "
                                  "paired with the render's; median and 95th percentile of |photo - render| in pixels",
    "the prediction's edges from the camera's uncertainty": "the grating equation's prediction redrawn with cameras "
                                                            "drawn from the calibration's standard deviations: how far "
                                                            "each band edge moves (RMS over the draws)",
    "fitted camera": "calibration.json's camera with one standard deviation from its fit",
    "worst region (relative error, median)": "the region with the largest median |photo / render - 1| after the one "
                                             "photometric scale (table: error per region)",
    "lens model and its uncertainty": "the board views' lens model (calibrate --model auto), the std of where a ray "
                                      "lands from the fit's covariance (worst direction), and the cross-validation of "
                                      "two fits from disjoint halves of the views (mrcal's practice)",
    "lens vignetting": "the lens's falloff towards the corners fitted by calibrate DATASET (the walls of every photo "
                       "against renders); when applied, the render is multiplied by it before every comparison",
    "regions at the calibrated exposure": "regions whose photo and render means agree within the z bound, from the "
                                          "photo's, the render's and the exposure's noise (table below)",
}
CALIBRATION_TIPS = {"value": "as fitted (calibration.json)", "std": "one standard deviation from the calibration's fit",
                    "quantity": "fx, fy: focal lengths; cx, cy: principal point; position: the camera centre in the "
                                "scene's frame; dist: OpenCV's distortion coefficients"}
FRINGE_TIPS = {"median px": "median |offset| over the paired band edges, in pixels",
               "p95 px": "95th percentile of |offset|", "edges": "paired edges measured",
               "comparison": "which two images' band edges (or hue crossings) are paired"}
ERROR_TIPS = {"relative error median": "median over the region of |photo / render - 1| (channel sums, after the "
                                       "photometric scale)",
              "CIEDE2000 median": "median colour difference Delta E 2000 of the display images (1 is about one just "
                                  "noticeable difference)",
              "FLIP median": "median of NVIDIA's FLIP perceptual difference (0 same, 1 most different)",
              "pixels": "pixels of the region in the image"}


def summary_block(report: dict[str, Any], lens_figure: str = "") -> str:
    """The page's first block after the verdict: the fringe offsets against the prediction's
    camera uncertainty, the fitted camera with its standard deviations, the worst region; then
    ``lens_figure`` (reports.page.lens_maps.figure_html: the lens row's maps), where given."""
    fo = report["fringe_offset_px"]
    spread = report["cd"].get("prediction_uncertainty")
    cal = report["calibration"]
    std = cal.get("std") or {}
    fmt = page.format_number
    rows = {"photo vs render band edges": f"median {fmt(fo.get('median'), 3)} px, p95 {fmt(fo.get('p95'), 3)} px "
                                          f"({fo.get('count')} edges)",
            "the prediction's edges from the camera's uncertainty": (
                f"RMS {fmt(spread['edge_rms_px_median'], 3)} px median, {fmt(spread['edge_rms_px_p95'], 3)} px p95 "
                f"({spread['draws']} cameras drawn within the calibration's std)"
                if isinstance(spread, dict) else str(spread)),
            "fitted camera": f"fx {fmt(cal['fx'])} +- {fmt(std.get('fx'), 2)} px, field of view "
                             f"{fmt(cal['fov_x_deg'])} deg, rotation +- {fmt(std.get('rotation_deg'), 2)} deg, centre +- "
                             f"{fmt(1000 * std['translation_m'] if 'translation_m' in std else None, 2)} mm"}
    regions: dict[str, float] = {name: float(entry["relative error"]["median"]) for name, entry in
                                 report["metrics"]["per_region"].items() if name != "all" and entry.get("relative error")}
    if regions:
        worst = max(regions, key=lambda name: regions[name])
        rows["worst region (relative error, median)"] = f"{worst}: {fmt(regions[worst], 3)}"
    rows["lens model and its uncertainty"] = _lens_row(cal)
    rows["lens vignetting"] = _vignetting_row((report.get("photometric_scale") or {}).get("vignetting") or {})
    tested = (report.get("region_test") or {}).get("regions") or {}
    compared = {name: row for name, row in tested.items() if "z" in row}
    if compared:
        flagged = [f"{name} (z {fmt(row['z'], 2)})" for name, row in compared.items() if not row["consistent"]]
        rows["regions at the calibrated exposure"] = (
            f"{len(compared) - len(flagged)} of {len(compared)} consistent (|z| <= "
            f"{fmt(report['region_test']['z_consistent'], 2)})" + ("; not: " + ", ".join(flagged) if flagged else ""))
    return "<section id='summary'>" + page.key_values(rows, tips=SUMMARY_TIPS) + lens_figure + "</section>"


def _lens_row(cal: dict[str, Any]) -> str:
    """The lens model, where a ray lands (the calibration's projection uncertainty), and its cross-validation."""
    unc, cross = cal.get("projection_uncertainty_px"), cal.get("cross_validation")
    text = cal.get("model", "pinhole")
    if unc:
        known = [unc[k] for k in ("top_left", "top_right", "bottom_left", "bottom_right") if unc.get(k) is not None]
        at_corners = (f"{max(known):.2f} px at the corners" if known else "no ray through the image corners")
        if known and len(known) < 4:
            at_corners += f" ({4 - len(known)} of 4 corners have no ray)"
        text += f"; a ray lands within +- {unc['centre']:.2f} px at the centre, {at_corners}"
        over_cd = cal.get("projection_uncertainty_cd_px")
        text += (f", {over_cd['median']:.2f} px over the CD (at most {over_cd['max']:.2f})" if over_cd else "") + " (1 std)"
    if cross:
        text += (f"; two halves of the board views differ by {cross['diff_median_px']:.2f} px (median) against "
                 f"{cross['predicted_median_px']:.2f} predicted" + (": the model is too poor for the data"
                                                                      if cross.get("too_poor") else ""))
    return text


def _vignetting_row(record: dict[str, Any]) -> str:
    """Applied (with the corners' falloff per channel) or not, and why (calibration.intrinsics.vignetting)."""
    if not record.get("applied"):
        return f"not applied: {record.get('why', 'not recorded')}"
    corners = record.get("corners") or {}
    darker = ", ".join(f"{ch} {100 * (1 - min(values)):.0f} %" for ch, values in corners.items())
    return f"applied to the render: corners darker by up to {darker} ({record.get('why', '')})"


def calibration_table(summary: dict[str, Any]) -> str:
    """The fitted camera as quantity / value / standard deviation / unit rows (the calibration's
    ``std``; '-' where it gives none), then where it came from."""
    std = summary.get("std") or {}
    rows = [{"quantity": key, "value": summary.get(key), "std": std.get(std_key) if std_key else None, "unit": unit}
            for key, unit, std_key in CALIBRATION_ROWS]
    rows.append({"quantity": "rotation", "value": None, "std": std.get("rotation_deg"), "unit": "deg"})
    lens = LENS_MODELS.get(summary.get("model", "pinhole"), LENS_MODELS["pinhole"])
    rows.append({"quantity": f"dist, {lens.name} ({', '.join(lens.coefficients)})", "value": summary.get("dist"),
                 "std": None, "unit": ""})
    where = {k: summary.get(k) for k in ("source", "pose_of", "scene", "width", "height")}
    return (page.table(rows, caption="the fitted camera; std from the calibration", tips=CALIBRATION_TIPS)
            + page.key_values(where))


REGION_TEST_TIPS = {
    "photo - render": "difference of the channel sums of the region means, in the photo's units (1 = white level)",
    "relative": "that difference over the render's channel sum",
    "z": "the difference over its standard deviation from the sources on the right",
    "std photo noise": "the photo's own noise: its sensor model or the region's second differences, the larger",
    "std render noise": "the render's Monte Carlo noise: the variance between its passes",
    "std exposure": "the calibration's exposure standard deviation times the render's mean",
}


def region_test_html(test: dict[str, Any]) -> str:
    """The per-region z-score table (reports.compare.regions), with what each column means."""
    rows = []
    for name, row in (test.get("regions") or {}).items():
        std = row.get("std") or {}
        rows.append({"region": name, "pixels": row.get("pixels"), "photo - render": row.get("photo_minus_render"),
                     "relative": row.get("relative"), "z": row.get("z"),
                     "consistent": {True: "yes", False: "no"}.get(row.get("consistent"), "-"),
                     "std photo noise": std.get("photo noise"), "std render noise": std.get("render noise"),
                     "std exposure": std.get("exposure"), "status": row.get("status")})
    noise = test.get("photo_noise") or {}
    notes = page.key_values({"consistent when": f"|z| <= {page.format_number(test.get('z_consistent'), 2)}",
                             "photo's sensor model": (f"variance = {page.format_number(noise.get('shot'), 3)} x level + "
                                                      f"{page.format_number(noise.get('read'), 3)}" if noise else None),
                             "cameras drawn for the regions": test.get("camera_draws"),
                             "pixels left out at region borders": test.get("border_px"), "how": test.get("how"),
                             "caveat": test.get("caveat")})
    return "<div id='region-test'>" + page.table(rows, caption="per region: photo mean against render mean",
                                                  tips=REGION_TEST_TIPS) + notes + "</div>"

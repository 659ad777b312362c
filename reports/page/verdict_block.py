"""The verdict block at the top of a report page: what the scene fit says about the photo.

From RUN/fit/scene_fit.json (reports.scene_fit.job): the verdict in words, the parameters
that moved (nominal, fitted, std), the band-edge residuals against the prediction before
and after the fit, the test's numbers, and, where the fitted scene was re-rendered, the
photo-vs-render fringe offsets with the scene file and with the fitted scene.
"""

from __future__ import annotations

import html
from typing import Any

from reports.page import html as page
from reports.scene_fit.verdict_record import Outcome, Verdict

HEADLINES = {
    Outcome.CONSISTENT: "Consistent: the photo agrees with the scene file within the measured uncertainty",
    Outcome.MODEL: "Model: the scene file is off; these parameters explain the photo",
    Outcome.CAMERA: "Camera: the disagreement lies within the calibration's uncertainty",
    Outcome.UNEXPLAINED: "Unexplained: neither the camera nor the free scene parameters explain the photo",
}


def report_verdict(scene_fit: dict[str, Any], offsets_before: dict | None, offsets_after: dict | None) -> dict[str, Any]:
    """report.json's ``verdict``: the fit's verdict with the renders' fringe offsets before and after."""
    v = Verdict.from_json(scene_fit["verdict"])
    return {"verdict": v.outcome.value, "why": v.why, "test": v.test, "parameters": [p.to_json() for p in v.parameters],
            "residuals_before_px": v.residuals_before_px.to_json(), "residuals_after_px": v.residuals_after_px.to_json(),
            "largest_residuals": list(v.largest_residuals or []),
            "camera_fit": None if v.camera_fit is None else v.camera_fit.to_json(),
            "fitted_parameters": scene_fit["parameters"], "held": scene_fit.get("held", {}),
            "bias_correction": scene_fit.get("bias_correction"),
            "fringe_offset_px_nominal_scene": offsets_before, "fringe_offset_px_fitted_scene": offsets_after}


def _offset_text(s: dict | None) -> str:
    if not s or s.get("median") is None:
        return "-"
    return f"median {s['median']:.2f} px, p95 {s['p95']:.2f} px ({s['count']} edges)"


def _noise_text(test: dict[str, Any]) -> str:
    """The measured noise per group: ``noise_px`` {group: px}, or an older record's band-edge ``edge_noise_px``."""
    noise = test.get("noise_px") or {"band edges": test.get("edge_noise_px", float("nan"))}
    return ", ".join(f"{name} {value:.2f} px" for name, value in noise.items())


def _bias_text(record: dict[str, Any]) -> str:
    """Whether the forward model's own offsets (measured on a render, reports.scene_fit.bias) were
    taken off each photo's band edges, and, where none was, what that leaves out."""
    if record.get("renders") is None:
        text, used = record.get("why", "no renders given"), False
    else:
        views = {name: note for name, note in record.items() if isinstance(note, dict)}
        used = any(note.get("used") for note in views.values())
        text = "; ".join(f"{name}: taken off" if note.get("used") else f"{name}: not used ({note.get('why', '')})"
                         for name, note in views.items())
    if not used:
        text += (". Without them the band edges' systematic offsets are not in the stds, and a consistent scene "
                 "can be called otherwise (draft seed-0 dataset, 4-spp renders: 1 of 12 realisations called model)")
    return text


def verdict_html(verdict: dict[str, Any]) -> str:
    """The block's HTML (every text escaped or built by reports.page.html)."""
    kind = verdict["verdict"]
    parts = [f"<div class='verdict verdict-{html.escape(kind)}'><b>{html.escape(HEADLINES.get(kind, kind))}</b>"
             f"<br>{html.escape(verdict['why'])}</div>"]
    if verdict["parameters"]:
        parts.append(page.table([{"parameter": p["component"], "scene file": p["nominal"], "fitted": p["fitted"],
                                  "std": p["std"], "moved (std)": p["sigmas"]} for p in verdict["parameters"]],
                                caption="parameters that had to move"))
    test = verdict["test"]
    noise, camera = test["noise_only"], test.get("noise_and_camera")
    rows = {"band edges vs prediction, scene file": _offset_text(verdict["residuals_before_px"]),
            "band edges vs prediction, fitted scene": _offset_text(verdict["residuals_after_px"]),
            "photo vs render, scene file": _offset_text(verdict.get("fringe_offset_px_nominal_scene")),
            "photo vs render, fitted scene": _offset_text(verdict.get("fringe_offset_px_fitted_scene")),
            "test": f"Wald statistic {noise['statistic']:.1f} on {noise['dof']} dof, p = {noise['p_value']:.2g} "
                    f"(noise {_noise_text(test)}, measured; alpha {test['alpha']:g})",
            "with the camera's uncertainty": "-" if camera is None else
            f"Wald statistic {camera['statistic']:.1f}, p = {camera['p_value']:.2g}"}
    if verdict.get("bias_correction"):
        rows["the forward model's own offsets"] = _bias_text(verdict["bias_correction"])
    camera_fit = verdict.get("camera_fit")
    if camera_fit:
        moved = ", ".join(f"{k} {v:.1f}" for k, v in list(camera_fit["moved_std"].items())[:3])
        rows["camera alone, within its uncertainty"] = (f"band edges median {camera_fit['median_px']:.2f} px; "
                                                        f"moved (std): {moved}")
    parts.append(page.key_values(rows))
    if verdict.get("largest_residuals"):
        parts.append(page.table(verdict["largest_residuals"], caption="largest residuals after the fit"))
    return "<section id='verdict'>" + "".join(parts) + "</section>"

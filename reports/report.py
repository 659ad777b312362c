"""``workbench report``: a photo and a render of the same view compared, written to a folder.

DIR/report.json holds every number on the page (``fringe_offset_px``: {median, p95,
count} of the photo-render band-edge offsets where both show the edge with quality
``ok``), DIR/fringes.csv every band edge found (photo, render, prediction) and
DIR/report.html the page (reports.page.html). Steps:

1. The camera: the calibration's fitted camera for the photo (calibration.calibration_file); the
   scene's camera is replaced by it, so prediction, masks and render share its pixels.
2. Photo (reports.compare.images.read_photo: calibration.raw.decode) and render (EXR) as linear camera
   RGB, same size. With a bracket (``brackets``), the photo's clipped pixels are filled from
   its darker frames (reports.compare.exposure_merge): the filled photo is what the page shows and
   what prediction, hues and maps are measured on; photo and render are compared through
   the photo's own saturation as taken (``fringe_offset_px``) and, unclipped, on the filled
   photo (``fringe_offset_unclipped_px``). Where the calibration applied the lens's
   vignetting (calibration.intrinsics.vignetting), the render is multiplied by it first: the render
   as this lens records it, in every comparison below.
3. Regions from a shape-id render (reports.compare.images.region_masks); one photometric scale
   fitted on the walls brings the render to the photo's units.
4. The CD: rim ellipses found in both images; the grating-equation prediction
   (renderer.trace.prediction); band edges along circles and radii (reports.fringes.band_edges) in photo,
   render and prediction, paired, offsets in pixels and degrees. Also relative to each
   image's own CD: the photo's grid moved by the affine map between the two rim ellipses.
   Hue crossings (reports.fringes.hue.find_hue_crossings: where the equivalent wavelength
   passes 440, 460, ... nm) along the circles, paired the same way (``hue_offset_px``).
   The prediction's uncertainty band: cameras drawn within the calibration's standard
   deviations (prediction_band), plotted on the fringe plot.
5. Error maps (reports.compare.metrics) and per-region statistics.
6. The efficiency tables the render and the prediction read, each with the truncation
   error it records (reports.table_error; report.json's ``tables``, "not recorded" for a
   table built before tables recorded it).

With a scene fit (``Inputs.scene_fit``: its scene_fit.json), report.json's ``verdict``
(reports.page.verdict_block.report_verdict) and the page's first block say whether the photo
agrees with the scene file and, if not, whether the model or the camera explains it.

Problems that do not stop the rest (the CD not in view, no fringes visible, no rim found)
are reported on the page and in report.json under ``messages``.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from calibration.calibration_file import FittedCamera, check_scene, read_camera, vignetting_record
from calibration.intrinsics.vignetting import relative_illumination, vignetting_summary
from renderer.scene import load_scene
from renderer.trace.prediction import CDGeometry, Prediction, cd_bbox, cd_geometry, predict
from reports.compare import images, metrics
from reports.compare.merged_photo import read_merged_photo
from reports.compare.regions import region_test
from reports.fringes import band_edges as fringes
from reports.fringes import polar
from reports.fringes.hue import HUE_LEVELS_NM, find_hue_crossings, hue_scale
from reports.fringes.prediction_band import CAMERA_STD_KEYS, draw_cameras
from reports.fringes.rim import Rim, fit_rim
from reports.page import html as page
from reports.page import lens_maps
from reports.page import tiles as image_tiles
from reports.page.fringe_overlay import OVERLAY_LEGEND, offset_plot, overlay_svg
from reports.page.fringe_plot import BAND_SIGMAS, fringe_plot
from reports.page.run_index import thumbnail_png
from reports.page.study_figures import study_sections as study_sections_of
from reports.page.summary import ERROR_TIPS, FRINGE_TIPS, calibration_table, region_test_html, summary_block
from reports.page.verdict_block import report_verdict, verdict_html
from reports.table_error import report_tables, tables_html, unrecorded_messages
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text

REPORT_FORMAT = "workbench-report"
CD_MAP_MARGIN_PX = 2
FLIP_MAX = 1.0
RELATIVE_MAX = 1.0
DELTA_E_MAX = 20.0
UNCERTAINTY_DRAWS = 4  # cameras drawn within the calibration's standard deviations (about 1.7 s each at 640 x 480)
MIN_OK_EDGES = 3  # fewer good edges in the photo than this: "no fringes visible"
MIN_PREDICTION_EDGES = 5  # fewer unsaturated photo edges than this: the prediction-photo median is said to rest on few
OFFSET_LABELS = {"photo_render": "photo vs render", "prediction_photo": "prediction vs photo",
                 "prediction_render": "prediction vs render",
                 "photo_render_relative_to_rim": "photo vs render, each relative to its own rim"}


@dataclasses.dataclass
class Inputs:
    photo: Path
    render: Path
    calibration: Path
    scene: str
    out: Path
    studies: tuple[Path, ...] = ()
    brackets: tuple[Path, ...] = ()  # darker frames of the photo's view, for its clipped highlights
    brackets_strict: bool = True  # a frame that does not fit is an error (else it is left out, with the reason)
    scene_fit: Path | None = None  # the scene fit's scene_fit.json: its verdict heads the page
    offsets_nominal_scene: dict | None = None  # photo-vs-render offsets with the scene file's render (a re-render's before)


def _scene_with_camera(scene: str, fitted: FittedCamera):
    spec = load_scene(scene)
    check_scene(fitted, spec, scene)
    return dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, model=fitted.model))


def _check_sizes(photo: np.ndarray, render: np.ndarray, fitted: FittedCamera, inputs: Inputs) -> None:
    size = (fitted.model.height, fitted.model.width)
    if photo.shape[:2] != render.shape[:2]:
        raise UserInputError(f"the photo is {photo.shape[1]} x {photo.shape[0]} but the render is "
                             f"{render.shape[1]} x {render.shape[0]}: they must share one pixel grid", field="--render",
                             expected="a render made with the calibration's camera", got=str(inputs.render))
    if photo.shape[:2] != size:
        raise UserInputError(f"the photo is {photo.shape[1]} x {photo.shape[0]} but the calibration's camera is "
                             f"{size[1]} x {size[0]}", field="--calibration", got=str(inputs.calibration))


def _edge_rows(source: str, grid_name: str, edges: list[fringes.Edge]) -> list[dict]:
    return [{"source": source, "grid": grid_name, **e.to_json()} for e in edges]


def _pair_rows(pairs: list[fringes.EdgePair]) -> list[dict]:
    rows = []
    for p in pairs:
        kind, profile, order, channel, band, side = p.key
        rows.append({"kind": kind, "profile": profile, "at": p.a.label, "order": order, "channel": channel, "band": band,
                     "side": side, "coordinate_a": p.a.coordinate, "coordinate_b": p.b.coordinate,
                     "offset_px": p.offset_px, "offset_deg": p.offset_deg})
    return rows


def _sampled_prediction(pred: Prediction, grid: polar.PolarGrid) -> np.ndarray:
    return np.stack([polar.sample(pred.channel_image(m).transpose(1, 2, 0), grid, robust=True)
                     for m in pred.orders]).transpose(0, 3, 1, 2)


def _correlation(photo: images.Photo) -> float:
    """How far the photo's noise is shared (reports.fringes.band_edges): 2 px for a demosaiced raw photo."""
    return fringes.MOSAIC_CORRELATION_PX if photo.kind == "raw" else fringes.NOISE_CORRELATION_PX


def measure_fringes(pred: Prediction, photo: images.Photo, render: np.ndarray, grids: tuple[polar.PolarGrid, ...],
                    focal_px: float, as_taken: images.Photo | None = None) -> dict[str, Any]:
    """Band edges in prediction, photo and render on ``grids``; pairs and summaries.

    ``photo`` is the photo as measured: with its clipped highlights filled from a bracket
    (reports.compare.exposure_merge) when there is one, so that its bands have half-maximum edges and
    hues to set against the prediction. ``as_taken`` is the single frame before filling: photo
    and render are compared through its sensor (its mosaic and saturation), so a band that
    saturates it saturates the render alike and its sharp edges count too. Without a bracket
    the two are the same photo. With one, ``photo_render_unclipped`` pairs the filled photo's
    half-maximum edges with the render's."""
    as_taken = as_taken if as_taken is not None else photo
    merged = as_taken is not photo
    edges: dict[str, list] = {"prediction": [], "photo": [], "render": [], "render_through_photo_sensor": []}
    if merged:
        edges["photo_as_taken"] = []
    pairs: dict[str, list] = {"photo_render": [], "prediction_photo": [], "prediction_render": []}
    if merged:
        pairs["photo_render_unclipped"] = []
    through_sensor = images.through_photo_sensor(render, as_taken)
    for grid in grids:
        sampled = _sampled_prediction(pred, grid)
        found = {"prediction": fringes.find_edges(grid, sampled, pred.orders),
                 "photo": fringes.find_edges(grid, sampled, pred.orders, photo.rgb, photo.clipped, _correlation(photo)),
                 "render": fringes.find_edges(grid, sampled, pred.orders, render),
                 "render_through_photo_sensor": fringes.find_edges(grid, sampled, pred.orders, through_sensor,
                                                                   as_taken.clipped, _correlation(as_taken))}
        if merged:
            found["photo_as_taken"] = fringes.find_edges(grid, sampled, pred.orders, as_taken.rgb, as_taken.clipped,
                                                         _correlation(as_taken))
            pairs["photo_render_unclipped"] += fringes.pair_edges(grid, found["photo"], found["render"], focal_px)
        for name, e in found.items():
            edges[name] += [(grid.kind, x) for x in e]
        pairs["photo_render"] += fringes.pair_edges(grid, found["photo_as_taken" if merged else "photo"],
                                                    found["render_through_photo_sensor"], focal_px,
                                                    accept=("ok", "clipped"))
        pairs["prediction_photo"] += fringes.pair_edges(grid, found["prediction"], found["photo"], focal_px)
        pairs["prediction_render"] += fringes.pair_edges(grid, found["prediction"], found["render"], focal_px)
    hue = measure_hue(pred, photo, render, grids[0], focal_px)
    summary = {k: fringes.offset_summary(v) for k, v in pairs.items()}
    return {"edges": edges, "pairs": pairs, "summary": summary, "hue": hue}


def measure_hue(pred: Prediction, photo: images.Photo, render: np.ndarray, circles: polar.PolarGrid,
                focal_px: float) -> dict[str, Any]:
    """Hue crossings (reports.fringes.hue.find_hue_crossings) along the circles in prediction, photo
    and render; pairs and summaries, as for the band edges."""
    scale = hue_scale(pred.wavelengths_nm, pred.weights, pred.white)
    sampled = _sampled_prediction(pred, circles)
    found = {"prediction": find_hue_crossings(circles, sampled, pred.orders, scale),
             "photo": find_hue_crossings(circles, sampled, pred.orders, scale, photo.rgb, _correlation(photo),
                                         clipped=photo.clipped),
             "render": find_hue_crossings(circles, sampled, pred.orders, scale, render)}
    pairs = {"photo_render": fringes.pair_edges(circles, found["photo"], found["render"], focal_px),
             "prediction_photo": fringes.pair_edges(circles, found["prediction"], found["photo"], focal_px),
             "prediction_render": fringes.pair_edges(circles, found["prediction"], found["render"], focal_px)}
    return {"edges": {k: [(circles.kind, e) for e in v] for k, v in found.items()}, "pairs": pairs,
            "summary": {k: fringes.offset_summary(v) for k, v in pairs.items()},
            "scale_nm": [float(scale.wavelengths_nm[0]), float(scale.wavelengths_nm[-1])]}


def _quality_counts(edges: list) -> dict[str, int]:
    counts: dict[str, int] = {}
    for _, e in edges:
        counts[e.quality] = counts.get(e.quality, 0) + 1
    return counts


def prediction_band(spec, camera, std: dict, grids, reference: list[fringes.Edge], draws: int = UNCERTAINTY_DRAWS,
                    seed: int = 0) -> dict[tuple, float]:
    """The prediction's uncertainty band: for cameras drawn within the calibration's standard
    deviations (reports.fringes.prediction_band.draw_cameras), the RMS distance (px) of each predicted band
    edge from where ``camera`` puts it (``reference``: that camera's predicted edges), by edge key.
    The band is the reference edge +- ``BAND_SIGMAS`` times it."""
    ref = {e.key(): e for e in reference}
    spreads: dict[tuple, list[float]] = {}
    for drawn_camera in draw_cameras(camera, std, draws, seed):
        drawn = predict(spec, drawn_camera)
        for grid in grids:
            for e in fringes.find_edges(grid, _sampled_prediction(drawn, grid), drawn.orders):
                r = ref.get(e.key())
                if r is not None and np.isfinite(e.x) and np.isfinite(r.x):
                    spreads.setdefault(e.key(), []).append(float(np.hypot(e.x - r.x, e.y - r.y)))
    return {key: float(np.sqrt(np.mean(np.square(v)))) for key, v in spreads.items() if len(v) == draws}


def _prediction_spread(spec, fitted: FittedCamera, grids, reference: list) -> tuple[dict[str, Any] | None, dict[tuple, float]]:
    """The band (prediction_band) for the fitted camera, summarised, and per edge."""
    std = fitted.std or {}
    keys = [k for k in CAMERA_STD_KEYS if isinstance(std.get(k), (int, float))]
    if not keys:
        return None, {}
    band = prediction_band(spec, fitted.model, std, grids, [e for _, e in reference])
    values = list(band.values())
    return ({"draws": UNCERTAINTY_DRAWS, "varied": keys, "band_sigmas": BAND_SIGMAS,
             "edge_rms_px_median": float(np.median(values)) if values else None,
             "edge_rms_px_p95": float(np.percentile(values, 95)) if values else None}, band)


def _cd_result(pred: Prediction, cd: CDGeometry, expected_rim: np.ndarray, photo_rim: Rim | None,
               render_rim: Rim | None, measured: dict[str, Any]) -> dict[str, Any]:
    """report.json's ``cd`` entry from the prediction, the rims and the measured fringes."""
    return {
        "status": "measured", "orders_predicted": pred.orders, "period_um": cd.period_um,
        "top_dispersive": cd.top_dispersive, "prediction_seconds": pred.seconds,
        "prediction_weighting": {"weighting": pred.weighting, "efficiency_table": pred.efficiency_source,
                                 "order_efficiency": None if pred.order_efficiency is None else
                                 {str(m): float(c) for m, c in zip(pred.orders, pred.order_efficiency, strict=True)}},
        "rim": {"expected_center_px": expected_rim.mean(axis=0).tolist(),
                "photo": photo_rim.to_json() if photo_rim else None, "render": render_rim.to_json() if render_rim else None},
        "edge_quality": {name: _quality_counts(e) for name, e in measured["edges"].items()},
        "offsets": measured["summary"],
        "hue": {"offsets": measured["hue"]["summary"], "scale_nm": measured["hue"]["scale_nm"],
                "levels_nm": list(HUE_LEVELS_NM),
                "quality": {name: _quality_counts(e) for name, e in measured["hue"]["edges"].items()},
                "how": "along circles, where the camera's hue (white-balanced on the light) turned into an equivalent "
                       "wavelength with its spectral sensitivities passes each level; the prediction's hue leaves out "
                       "the diffraction efficiency's change with wavelength, so its offsets carry that bias"},
    }


def _offsets_relative_to_rim(pred: Prediction, grids: tuple[polar.PolarGrid, ...], own: tuple[polar.PolarGrid, ...],
                             photo: images.Photo, render: np.ndarray) -> dict[str, Any]:
    """{median, p95, count} of photo-render edge offsets, each image relative to its own CD: the
    photo's edges on the grids ``own`` (moved by the affine map between the rims), the render's on ``grids``."""
    relative = []
    for grid_ref, grid_own in zip(grids, own, strict=True):
        sampled = _sampled_prediction(pred, grid_ref)
        photo_edges = fringes.find_edges(grid_own, sampled, pred.orders, photo.rgb, photo.clipped, _correlation(photo))
        render_edges = fringes.find_edges(grid_ref, sampled, pred.orders, render)
        by_key = {e.key(): e for e in photo_edges}
        step = float(np.nanmean(grid_ref.step_px()))
        for a in render_edges:
            b = by_key.get(a.key())
            if b is not None and a.quality == "ok" and b.quality == "ok":
                relative.append(abs(b.position - a.position) * step)
    return {"median": float(np.median(relative)) if relative else float("nan"),
            "p95": float(np.percentile(relative, 95)) if relative else float("nan"), "count": len(relative)}


def _cd_notes(result: dict[str, Any], cd: CDGeometry, photo: images.Photo, messages: list[str],
              problems: list[str]) -> None:
    """What the reader should know about the CD's measurement (``messages``) and what failed (``problems``)."""
    if not cd.top_dispersive:
        messages.append("CD: the scene's polycarbonate top is not dispersive (the mean index over 360-830 nm): the "
                        "orders' directions in air are exact (the grating under it uses the same index), but the "
                        "top's refraction and Fresnel transmission are the mean index's, which may shift the render's "
                        "colours by 2-4 nm against a real CD's; the prediction uses the same top")
    unsaturated = result["offsets"]["prediction_photo"]["count"]
    if unsaturated < MIN_PREDICTION_EDGES and photo.clipped.any():
        messages.append(f"CD: the prediction is compared with the photo on {unsaturated} band edges only: the photo's bands "
                        "saturate (a saturated band's edge is not a half-maximum edge); photo and render are compared "
                        "through the photo's saturation instead")
    photo_quality = result["edge_quality"]["photo"]
    ok_photo = photo_quality.get("ok", 0) + photo_quality.get("clipped", 0)  # a saturated band is visible
    if ok_photo < MIN_OK_EDGES:
        problems.append(f"CD: no fringes visible in the photo where the grating equation puts them ({ok_photo} band "
                        f"edges of quality ok; {result['edge_quality']['photo']})")


def analyse_cd(spec, fitted: FittedCamera, photo: images.Photo, render: np.ndarray, messages: list[str],
               problems: list[str], as_taken: images.Photo | None = None) -> dict[str, Any]:
    """Everything about the CD (module docstring, step 4); ``problems`` for what could not be
    done, ``messages`` for what the reader should know; ``as_taken``: the photo before its
    highlights were filled from a bracket (measure_fringes)."""
    started = time.perf_counter()
    camera = fitted.model
    try:
        cd = cd_geometry(spec)
    except UserInputError as error:
        problems.append(f"CD: {error.reason}")
        return {"status": "no CD"}
    if cd_bbox(camera, cd) is None:
        problems.append("CD: the camera does not see the CD; the rest of the report is complete")
        return {"status": "not in view"}
    pred = predict(spec, camera)
    expected_rim = camera.project(cd.rim_points(on_top=True))
    photo_rim = fit_rim(photo.rgb, expected_rim)
    render_rim = fit_rim(render, expected_rim)
    grids = polar.standard_grids(camera, cd)
    measured = measure_fringes(pred, photo, render, grids, camera.fx, as_taken)
    result = _cd_result(pred, cd, expected_rim, photo_rim, render_rim, measured)
    if photo_rim and render_rim:
        result["rim"]["photo_minus_render_center_px"] = [photo_rim.center[0] - render_rim.center[0],
                                                         photo_rim.center[1] - render_rim.center[1]]
        own = polar.standard_grids(camera, cd, render_rim.affine_to(photo_rim)[:2])
        result["offsets"]["photo_render_relative_to_rim"] = _offsets_relative_to_rim(pred, grids, own, photo, render)
    else:
        problems.append("CD: the rim ellipse was not found in " + " and ".join(
            name for name, rim in (("the photo", photo_rim), ("the render", render_rim)) if rim is None))
    _cd_notes(result, cd, photo, messages, problems)
    spread, band = _prediction_spread(spec, fitted, grids, measured["edges"]["prediction"])
    result["prediction_uncertainty"] = spread if spread else "the calibration gives no standard deviations"
    result["_band"] = band
    result["seconds"] = time.perf_counter() - started
    result["_measured"] = measured
    result["_radius_px"] = polar.rim_radius_px(camera, cd)
    return result


def _csv_text(rows: list[dict]) -> str:
    if not rows:
        return ""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def _clean(value: Any) -> Any:
    """JSON-safe: nan and inf become None, numpy scalars plain numbers, tuples lists."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items() if not str(k).startswith("_")}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(float(value)) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    return value


def _photo(inputs: Inputs, messages: list[str]) -> tuple[images.Photo, images.Photo]:
    """The report's photo, filled from its bracket (read_merged_photo)."""
    return read_merged_photo(inputs.photo, inputs.calibration, inputs.brackets, inputs.brackets_strict, messages)


def _error_maps(photo: np.ndarray, aligned: np.ndarray, photo_display: np.ndarray, render_display: np.ndarray,
                masks: dict[str, np.ndarray], messages: list[str]) -> tuple[dict[str, np.ndarray], float, str]:
    """The error maps (relative error, CIEDE2000 and, where installed, FLIP), the display exposure
    that brings the walls to mid grey, and FLIP's note. ``photo`` and ``aligned`` (the render in
    the photo's units) in camera RGB, the displays in linear sRGB."""
    walls = np.zeros(photo.shape[:2], bool)
    for name in images.WALL_REGIONS:
        walls |= masks.get(name, False)
    wall_level = float(np.median(photo_display[walls].mean(axis=1))) if walls.any() else float(np.median(photo_display))
    exposure = metrics.MID_GREY / max(wall_level, 1e-12)
    maps = {"relative error": metrics.relative_error(photo, aligned, float(np.median(photo[walls])) if walls.any()
                                                     else float(np.median(photo))),
            "CIEDE2000": metrics.ciede2000(photo_display, render_display, exposure)}
    flip_map, flip_note = metrics.flip(photo_display * exposure, render_display * exposure)
    if flip_map is not None:
        maps["FLIP"] = flip_map
    else:
        messages.append(f"FLIP: {flip_note}")
    return maps, exposure, flip_note


def _headline_offsets(cd: dict[str, Any]) -> dict[str, Any]:
    """report.json's headline offsets, taken from the CD's entry (None and count 0 where not measured)."""
    offsets = cd.get("offsets", {})
    headline = {"fringe_offset_px": offsets.get("photo_render", {"median": None, "p95": None, "count": 0})}
    if "photo_render_unclipped" in offsets:
        headline["fringe_offset_unclipped_px"] = offsets["photo_render_unclipped"]
    headline["prediction_offset_px"] = {"photo": offsets.get("prediction_photo"), "render": offsets.get("prediction_render")}
    hue_offsets = (cd.get("hue") or {}).get("offsets", {})
    headline["hue_offset_px"] = hue_offsets.get("photo_render", {"median": None, "p95": None, "count": 0})
    return headline


def _fringe_rows(cd: dict[str, Any]) -> tuple[list[dict], list[dict]]:
    """fringes.csv's rows (every edge found: band edges, then hue crossings) and the page's
    photo-render pairs."""
    edge_rows: list[dict] = []
    pair_rows: list[dict] = []
    if "_measured" in cd:
        for group in (cd["_measured"]["edges"], cd["_measured"]["hue"]["edges"]):  # band edges, then hue crossings
            for name, edges in group.items():
                for kind, e in edges:
                    edge_rows += _edge_rows(name, kind, [e])
        pair_rows = _pair_rows(cd["_measured"]["pairs"]["photo_render"] + cd["_measured"]["hue"]["pairs"]["photo_render"])
    return edge_rows, pair_rows


def _through_lens(render: np.ndarray, falloff: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """The render as the photo's lens records it: times its vignetting (calibration.intrinsics.vignetting), where applied."""
    return (render if falloff is None else (render * falloff).astype(np.float32)), falloff


def build_report(inputs: Inputs) -> dict[str, Any]:
    """Write DIR/report.json, DIR/fringes.csv and DIR/report.html; returns report.json's content."""
    started = time.perf_counter()
    messages: list[str] = []
    problems: list[str] = []
    fitted = read_camera(inputs.calibration, inputs.photo.name)
    spec = _scene_with_camera(inputs.scene, fitted)
    photo, as_taken = _photo(inputs, messages)
    render = images.read_linear(inputs.render, "--render")
    _check_sizes(photo.rgb, render, fitted, inputs)
    vignetting = vignetting_record(inputs.calibration)
    render, falloff = _through_lens(render, relative_illumination(vignetting, fitted.model))
    study_sections = study_sections_of(inputs.studies)
    masks = images.region_masks(spec)
    scale, wall_pixels = images.photometric_scale(photo.rgb, render, masks, photo.clipped)
    aligned = render * scale
    cd = analyse_cd(spec, fitted, photo, aligned, messages, problems, as_taken)
    tables = report_tables(inputs.render, (cd.get("prediction_weighting") or {}).get("efficiency_table"))
    messages += unrecorded_messages(tables)

    matrix = images.display_matrix(spec)
    photo_display, render_display = images.to_display(photo.rgb, matrix), images.to_display(aligned, matrix)
    maps, exposure, flip_note = _error_maps(photo.rgb, aligned, photo_display, render_display, masks, messages)
    limits = {"relative error": RELATIVE_MAX, "CIEDE2000": DELTA_E_MAX, "FLIP": FLIP_MAX}
    statistics = metrics.region_statistics(maps, masks)
    regions_tested = region_test(spec, fitted, as_taken, render, inputs.render, inputs.calibration, masks, falloff)

    report: dict[str, Any] = {
        "format": REPORT_FORMAT, "photo": str(inputs.photo), "render": str(inputs.render),
        "calibration": fitted.summary(), "scene": spec.name, "scene_source": spec.source,
        "size": [fitted.model.width, fitted.model.height], "photo_kind": photo.kind,
        "photo_decoding": photo.decoding,
        "photo_clipped_pixels": int(photo.clipped.sum()),
        "photometric_scale": {"render_to_photo": scale, "wall_pixels": wall_pixels, "how": "median of photo / render "
                              "(channel sums) over the walls", "vignetting": vignetting_summary(vignetting)},
        "display": {"camera_rgb_to_linear_srgb": matrix.tolist(), "white": "the scene's light",
                    "exposure_for_mid_grey_walls": exposure},
        "regions": {name: int(mask.sum()) for name, mask in masks.items()},
        "metrics": {"per_region": statistics, "flip": flip_note, "limits_shown": limits},
        "region_test": regions_tested, "cd": cd, "tables": tables, "problems": problems, "messages": messages,
    }
    report |= _headline_offsets(cd)
    if inputs.scene_fit is not None:
        report["verdict"] = report_verdict(json.loads(inputs.scene_fit.read_text()), inputs.offsets_nominal_scene,
                                           report["fringe_offset_px"] if inputs.offsets_nominal_scene else None)
    edge_rows, pair_rows = _fringe_rows(cd)
    report["seconds"] = time.perf_counter() - started

    inputs.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(inputs.out / "fringes.csv", _csv_text(edge_rows))
    tiles = image_tiles.pyramid({"photo": photo_display, "render": render_display})
    report["display"]["tiles"] = {key: value for key, value in tiles.items() if key != "tiles"}  # levels, codecs, quality
    html_text = _page(report, inputs, tiles, exposure, maps, limits, masks, cd, pair_rows,
                      study_sections)
    report["html_bytes"] = len(html_text.encode("utf-8"))
    clean = _clean(report)
    atomic_write_text(inputs.out / "report.json", json.dumps(clean, indent=2))
    thumbnail_png(photo_display, exposure, inputs.out / "thumbnail.png")  # a run's index page shows it
    atomic_write_text(inputs.out / "report.html", html_text)
    return clean


def _page(report, inputs: Inputs, tiles, exposure, maps, limits, masks, cd, pair_rows,
          study_sections) -> str:
    width, height = tiles["levels"][0]["width"], tiles["levels"][0]["height"]
    map_entries = {}
    for name, values in maps.items():  # at the overview's resolution: a 24 MP photo's maps stay small
        map_entries[name] = {"uri": page.png_data_uri(page.false_colour(image_tiles.overview_of(values), limits[name])),
                             "legend": f"0 to {limits[name]:g} ({'photo / render - 1' if name == 'relative error' else name})"}
    sections: list[tuple[str, str]] = []
    fo = report["fringe_offset_px"]
    summary_rows = []
    for name, s in (cd.get("offsets") or {}).items():
        summary_rows.append({"comparison": OFFSET_LABELS.get(name, name), "median px": s.get("median"),
                             "p95 px": s.get("p95"), "edges": s.get("count")})
    for name, s in ((cd.get("hue") or {}).get("offsets") or {}).items():
        summary_rows.append({"comparison": "hue crossings: " + OFFSET_LABELS.get(name, name), "median px": s.get("median"),
                             "p95 px": s.get("p95"), "edges": s.get("count")})
    levels = (cd.get("hue") or {}).get("levels_nm")
    fringe_html = page.table(summary_rows, caption=f"band-edge offsets (fringe_offset_px: median "
                                                   f"{page.format_number(fo.get('median'), 3)} px, p95 "
                                                   f"{page.format_number(fo.get('p95'), 3)} px, {fo.get('count')} edges); "
                                                   f"hue crossings (equivalent wavelength {page.format_value(levels)} nm)",
                             tips=FRINGE_TIPS)
    if "_measured" in cd:
        radius_px = cd["_radius_px"]
        plot = fringe_plot(cd["_measured"], radius_px, cd.get("_band"))
        fringe_html += f"<div><img alt='fringe radius against azimuth' src='{plot}'></div>"
        fringe_html += (f"<div><img alt='photo - render offsets against azimuth and radius' "
                        f"src='{offset_plot(cd['_measured'], radius_px)}'></div>")
        fringe_html += "<div class='scroll'>" + page.table(pair_rows, caption="photo vs render, edge by edge") + "</div>"
        rim = cd.get("rim", {})
        fringe_html += page.key_values({"photo rim": rim.get("photo"), "render rim": rim.get("render"),
                                        "photo - render centre (px)": rim.get("photo_minus_render_center_px"),
                                        "edge quality": cd.get("edge_quality"),
                                        "prediction uncertainty": cd.get("prediction_uncertainty")})
    else:
        fringe_html += f"<p>{page.html.escape(str(cd.get('status')))}</p>"
    sections.append(("CD fringes", fringe_html))
    region_rows = []
    for region, entry in report["metrics"]["per_region"].items():
        row: dict[str, Any] = {"region": region, "pixels": entry["pixels"]}
        for metric in maps:
            stats = entry.get(metric) or {}
            row[f"{metric} median"] = stats.get("median", float("nan"))
            row[f"{metric} p95"] = stats.get("p95", float("nan"))
        region_rows.append(row)
    sections.append(("error per region", page.table(region_rows, tips=ERROR_TIPS)))
    sections.append(("photo against render per region, at the calibrated exposure", region_test_html(report["region_test"])))
    sections.append(("calibration (the fitted camera)", calibration_table(report["calibration"])))
    sections.append(("inputs", page.key_values({"photo": report["photo"], "render": report["render"],
                                                "scene": report["scene"], "scene file": report["scene_source"],
                                                "photometric scale": report["photometric_scale"]["render_to_photo"],
                                                "report built in (s)": report["seconds"]})))
    sections.append(("efficiency tables (their own truncation error)", tables_html(report["tables"])))
    sections += study_sections
    title = f"report: {report['scene']} - {Path(report['photo']).name} vs {Path(report['render']).name}"
    verdict = ((verdict_html(report["verdict"]) if "verdict" in report else "")
               + summary_block(report, lens_maps.figure_html(inputs.calibration, masks.get("cd"))))
    return page.render_page(title=title, pyramid=tiles, exposure_ev=float(np.log2(exposure)), maps=map_entries,
                            sections=sections, notes=report["messages"], errors=report["problems"], verdict=verdict,
                            overlay=_overlay(cd, width, height), overlay_legend=OVERLAY_LEGEND)


def _overlay(cd: dict[str, Any], width: int, height: int) -> str:
    """The fringe overlay's SVG (reports.page.fringe_overlay), or nothing where the CD was not measured."""
    if "_measured" not in cd:
        return ""
    return overlay_svg(cd["_measured"], cd.get("_band"), cd["rim"]["expected_center_px"], width, height)

"""``workbench fit``: the scene parameters a dataset's photos constrain, and the verdict.

Steps: every photo of DATASET/photos with its camera from the calibration
(calibration.calibration_file.read_camera) and its clipped highlights filled from the dataset's
bracket frames of its view (reports.compare.merged_photo.read_merged_photo); the scene's ``[fit]`` table
(renderer.fit_parameters; the defaults without one); the forward model
(reports.scene_fit.model) fitted to all photos' band edges at once (reports.scene_fit.fit),
the camera's uncertainty propagated (reports.scene_fit.verdict.camera_effect); the
verdict (reports.scene_fit.verdict); DIR/scene_fit.json and DIR/fitted_scene.toml
(reports.scene_fit.outputs).
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from calibration.calibration_file import check_scene, read_camera
from calibration.dataset import dataset_files
from calibration.raw.decode import is_raw
from renderer.render import variance_path
from renderer.scene import load_scene
from renderer.trace.prediction import PREDICTION_STEP_NM
from reports.compare.images import read_linear
from reports.compare.merged_photo import read_merged_photo
from reports.fringes import band_edges as fringes
from reports.scene_fit.fit import FitSettings, SceneFitResult, fit_scene
from reports.scene_fit.model import FIT_SUPERSAMPLE, EdgeModel, View, photo_rim_points, view_grids
from reports.scene_fit.outputs import parameters_json, write_fitted_scene
from reports.scene_fit.verdict import camera_effect, judge
from reports.scene_fit.verdict_record import Verdict
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text
from workbench.core.version import versions

FIT_FORMAT = "workbench-scene-fit"


@dataclasses.dataclass
class FitInputs:
    dataset: Path
    scene: str
    calibration: Path
    out: Path
    photos: tuple[str, ...] = ()
    supersample: int = FIT_SUPERSAMPLE
    step_nm: float = PREDICTION_STEP_NM
    settings: FitSettings = dataclasses.field(default_factory=FitSettings)
    renders: Path | None = None  # NAME.exr per photo: the scene file through its calibrated camera (scene_fit_bias)


def load_views(inputs: FitInputs, spec) -> list[View]:
    """The photos with their cameras, filled highlights and fixed grids."""
    files = dataset_files(inputs.dataset)
    photos = files["photos"]
    if inputs.photos:
        photos = [p for p in photos if p.name in inputs.photos]
        missing = sorted(set(inputs.photos) - {p.name for p in photos})
        if missing:
            raise UserInputError(f"no such photo in the dataset: {', '.join(missing)}", file=inputs.dataset / "photos",
                                 field="--photo")
    views = []
    for path in photos:
        fitted = read_camera(inputs.calibration, path.name)
        check_scene(fitted, spec, inputs.scene)
        photo, _ = read_merged_photo(path, inputs.calibration, tuple(files["brackets"]), False, [])
        correlation = fringes.MOSAIC_CORRELATION_PX if is_raw(path) else fringes.NOISE_CORRELATION_PX
        views.append(View(path.name, fitted.model, photo, view_grids(spec, fitted.model), fitted.std or {}, correlation,
                          photo_rim_points(photo, fitted.model, spec), *_render(inputs.renders, path, photo)))
    return views


def _render(folder: Path | None, photo_path: Path, photo) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The photo's render of the scene file (``folder``/NAME.exr) and its variance between passes
    (NAME.variance.exr, where the render wrote one), or Nones without a folder."""
    if folder is None:
        return None, None
    path = folder / f"{photo_path.stem}.exr"
    if not path.is_file():
        raise UserInputError("no render of this photo's scene", file=path, field="--renders",
                             expected=f"{photo_path.stem}.exr, as `workbench render` writes it for the photo's "
                                      "calibrated scene (calibration's scenes/NAME.toml)")
    rgb = read_linear(path, "--renders")
    if rgb.shape[:2] != photo.rgb.shape[:2]:
        raise UserInputError("the render's size differs from the photo's", file=path, field="--renders",
                             expected=f"{photo.rgb.shape[1]} x {photo.rgb.shape[0]}", got=f"{rgb.shape[1]} x {rgb.shape[0]}")
    variance = variance_path(path)
    return rgb, read_linear(variance, "--renders") if variance.is_file() else None


def bias_record(model: EdgeModel, views: list[View], renders: Path | None) -> dict[str, Any]:
    """scene_fit.json's ``bias_correction``: per photo, what its render measured (reports.scene_fit.bias)."""
    if renders is None:
        return {"renders": None, "why": "no renders given: the forward model's offsets are not corrected"}
    out: dict[str, Any] = {"renders": str(renders)}
    for view, bias, note in zip(views, model.view_biases(), model.bias_notes, strict=True):
        out[view.name] = dict(note)
        if bias is not None:
            edges = np.array(list(bias.edges.values()))
            out[view.name] |= {"band_edge_keys": len(edges),
                               "band_offset_median_px": float(np.median(edges)) if len(edges) else None,
                               "rim_points": len(bias.rim_offsets),
                               "rim_offset_median_px": float(np.median(bias.rim_offsets)) if len(bias.rim_offsets)
                               else None}
    return out


def _record(inputs: FitInputs, spec, table, model: EdgeModel, result: SceneFitResult, judged: Verdict, views: list[View],
            seconds: dict[str, float]) -> dict[str, Any]:
    labels = table.labels()
    return {
        "format": FIT_FORMAT, "dataset": str(inputs.dataset), "scene": inputs.scene,
        "calibration": str(inputs.calibration), "photos": [v.name for v in views],
        "parameters": parameters_json(spec, table, result.nominal, result.values, result.std),
        "held": table.held | ({} if table.declared else {"(defaults)": "the scene has no [fit] table: the defaults "
                                                          "of renderer.fit_parameters.DEFAULT_FREE are fitted"}),
        "components": labels, "values": result.values.tolist(), "nominal_values": result.nominal.tolist(),
        "std_jacobian": result.std_jacobian.tolist(), "std_bootstrap": result.std_bootstrap.tolist(),
        "bias_correction": bias_record(model, views, inputs.renders),
        "correlations": np.round(result.correlations, 4).tolist(),
        "residuals_before_px": judged.residuals_before_px.to_json(),
        "residuals_after_px": judged.residuals_after_px.to_json(),
        "noise_px": result.noise_px, "verdict": judged.to_json(),
        "settings": {"supersample": inputs.supersample, "step_nm": inputs.step_nm,
                     **dataclasses.asdict(inputs.settings)},
        "rounds": result.log, "evaluations": result.evaluations,
        "versions": versions("numpy", "scipy", "nlopt", "opencv"), "timings": seconds,
    }


def run_fit(inputs: FitInputs) -> dict[str, Any]:
    """Fit, judge and write DIR/scene_fit.json and DIR/fitted_scene.toml; returns the record."""
    started = time.perf_counter()
    spec = load_scene(inputs.scene)
    table = spec.fit
    if table is None or not table.free:
        raise UserInputError("the scene has nothing to fit (no CD, or a [fit] table with no free parameter)",
                             file=spec.source, field="fit")
    if inputs.renders is not None and not inputs.renders.is_dir():
        raise UserInputError("no such folder", field="--renders", got=str(inputs.renders),
                             expected="a folder of NAME.exr renders, one per photo")
    views = load_views(inputs, spec)
    loaded = time.perf_counter()
    model = EdgeModel(spec, table, views, supersample=inputs.supersample, step_nm=inputs.step_nm)
    try:
        result = fit_scene(model, inputs.settings, lambda x, observed: camera_effect(model, x, observed))
    except ValueError as error:
        raise UserInputError(f"the photos do not constrain the scene: {error}", file=inputs.dataset / "photos") from None
    fitted = time.perf_counter()
    judged = judge(result, table.labels(), [p.name for p in table.free for _ in p.components],
                   [v.name for v in views])
    inputs.out.mkdir(parents=True, exist_ok=True)
    write_fitted_scene(spec, table, result.values, inputs.out,
                       f"{spec.name} with the scene fit's values (workbench fit; verdict: {judged.outcome})")
    seconds = {"load": loaded - started, "fit": fitted - loaded, "total": time.perf_counter() - started,
               "forward_model": model.seconds, "evaluations": model.evaluations}
    record = _record(inputs, spec, table, model, result, judged, views, seconds)
    atomic_write_text(inputs.out / "scene_fit.json", json.dumps(record, indent=2) + "\n")
    return record

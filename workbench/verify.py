"""``workbench verify DATASET --scene SCENE --out RUN``: photos to report in one resumable run.

Seven stages, in order, each with its own folder in RUN:

=============  =====================================================================  ==========================
stage          what it does                                                           inputs hashed
=============  =====================================================================  ==========================
plan           renderer.trace.planner on the run's scene: tables, orders, directions, cost  RUN/scene.toml
tables         the scene's efficiency tables, built (or resumed) in the user's cache  RUN/scene.toml
calibration    calibration.dataset on DATASET's photos/, brackets/, calibration/      those files, RUN/scene.toml
render         every photo's calibrated scene (calibration/scenes/NAME.toml),          the scenes
               rendered (render/NAME.exr)
fit            reports.scene_fit.job: the scene's [fit] parameters from the photos'    photos, brackets,
               band edges, the forward model's own offsets measured on the renders    calibration, renders,
               (reports.scene_fit.bias), and the verdict (fit/scene_fit.json,         RUN/scene.toml
               fitted_scene.toml; with the verdict ``model``, fit/scenes/NAME.toml:
               each photo's calibrated scene with the fitted values;
               fit/not_fitted.txt says why when there is nothing to fit or too few
               band edges)
rerender       with the verdict ``model``, each photo's fitted scene rendered          the fitted scenes
               (rerender/NAME.exr: the re-render that confirms the fit); else nothing
report         reports.report: each photo against its render, its clipped highlights  photos, renders, brackets,
               filled from the bracket frames that show its view, the fit's verdict   calibration, the fit
               first on the page; after a re-render, report/NAME/ compares the
               fitted scene's render and report/NAME/nominal/ the scene file's
=============  =====================================================================  ==========================

The tables stage builds whole tables: calibration re-renders the scene from many
cameras (renderer.rerender), and a whole table in the cache serves the render's plan too
(renderer.tables.table_plan), so the plan stage's planned fractions and costs are what a
render of the scene's camera alone would need, recorded for the user (RUN/plan/plan.txt).

RUN/scene.toml is the scene as the run uses it: the user's scene with every CD's and
grating's table at the preset's table preset (draft or paper) and paths made absolute.
Every photo is rendered and reported (each view shows the CD's fringes from another
angle and gets its own report); ``photos`` picks some. The render always has the photo's
size (the report compares pixel by pixel) and samples each region to what the report measures
there (renderer.render_target: the CD's band edges, as its own crop, the walls' scale, a floor
elsewhere; the preset's spp caps the frame); ``--spp N`` renders N samples everywhere instead
(the fixed render, the paper preset's 2045). The paper preset takes paper tables; the
paper's 978 x 734 frame is a dataset's (``workbench synth --preset full``).

A stage's key is the SHA-256 of its input files' bytes, its settings and the workbench
version; a finished stage is one whose folder holds its current key, and is skipped
(workbench.verify_run: the run's folder, its record, the staging of each stage and the
lock). A killed run leaves the staging folder; the next run with the same key keeps it
(a render resumes from its saved passes and finished photos, the report from its
finished photos, the table build from its finished chunks in the cache; the calibration,
one optimisation, starts again) and a changed key clears it. RUN/run.json records the
settings, versions, each stage's key, status, estimate and timings, and the summary.
verify never reads truth.json (``workbench score`` does, workbench.score).

On a dask.distributed cluster (``--scheduler ADDRESS``, or ``--workers N`` for a local one;
workbench.core.executor) the same stages run with their work as tasks: the tables' wavelength
chunks, the calibration's intrinsics and response (two tasks) and each photo's pose (one task
a photo, all at once when board views fix the intrinsics), the scene fit (one task: it is one
least-squares problem over every photo's band edges), every render pass (each with its own
seed and the client's Dr.Jit thread count, so a pass is the same bytes wherever it runs, merged
here by their sample counts) and each photo's report. Stages, keys and resuming are as without
a cluster: this process writes the records, the calibration and the renders; a report task
writes its photo's folder in the stage's staging folder; a worker renders one Mitsuba pass at
a time. The workers read the dataset, RUN and the cache's tables at the paths this process
names: a shared filesystem at the same paths. Each stage's ``dask_tasks`` in run.json counts
the tasks it sent to the cluster.
"""

from __future__ import annotations

import json
import os
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w
from PIL import Image
from tqdm import tqdm

from calibration.dataset import calibrate_dataset, dataset_files, stage_needs
from calibration.raw.checks import check_raw_file
from calibration.raw.decode import is_raw
from rcwa.structure import BUILTIN_STRUCTURES
from rcwa.table import build_table
from renderer.render import render
from renderer.render_target import FLOOR_SPP
from renderer.scene import CDSpec, GratingSpec, SceneSpec, load_scene
from renderer.tables import table_plan
from renderer.trace.planner import format_plan, plan_scene
from reports.page.run_index import write_run_index
from reports.page.study_figures import study_figures
from reports.report import Inputs, build_report
from reports.scene_fit.job import FitInputs, run_fit
from reports.scene_fit.outputs import write_fitted_scene
from reports.scene_fit.verdict_record import Outcome, Verdict
from workbench.core.errors import UserInputError
from workbench.core.executor import DaskExecutor
from workbench.core.files import atomic_write_text
from workbench.verify_run import PRESETS, STAGES, Run, VerifySettings, _say, open_run, read_record, run_lock, run_stage

__all__ = ["STAGES", "VerifySettings", "format_summary", "open_run", "read_record", "run_lock", "verify"]

DATASET_FOLDERS = ("photos", "brackets", "calibration")  # all calibration reads; never truth.json
PAPER_RESOLUTION = (978, 734)  # the paper's frame (renderer.render's paper preset)
# The scene's image aspect may differ from the photos' by its resolution's rounding: one pixel
# of 245 (cornell_cd: 326 x 245 for a 25 x 18.8 mm sensor) is 0.4 %; a different camera is off by far more.
ASPECT_TOLERANCE = 0.01
# Estimates of each stage's time on this 2-core machine (measured on draft cornell_cd datasets, 640 x 480):
SECONDS_PLAN = 3.0  # planner with its timed cost sweep
SECONDS_CALIBRATION_BASE = 3.0  # intrinsics from 20 board views and the response from a 5-photo bracket
SECONDS_PER_POSE = 7.0  # one photo's pose fit
SECONDS_PER_SAMPLE = 1.05e-6  # render: 81 s for 640 x 480 at 256 spp
SECONDS_RENDER_LOAD = 2.5  # building the Mitsuba scene, per photo
SECONDS_TARGET_CD = 30.0  # the targeted render's CD crop (renderer.render_target) and its region masks, per photo
SECONDS_PER_REPORT = 6.0  # one photo's report (masks, fringes, error maps, page)
SECONDS_FIT = 50.0  # the scene fit of a two-photo draft dataset (benchmarks/bench_scene_fit.py)
NOT_FITTED = "not_fitted.txt"  # in RUN/fit when the scene has nothing to fit or the photos too few edges (why)



# ---------------------------------------------------------------- inputs


def photo_size(path: Path) -> tuple[int, int]:
    """(width, height) of a photo as calibration decodes it (raw: LibRaw's visible size, after
    calibration.raw.checks refused a damaged or unsupported raw with the decode's own message)."""
    if is_raw(path):
        return check_raw_file(path)
    try:
        with Image.open(path) as image:
            return image.size
    except Exception as exc:  # noqa: BLE001 (Pillow raises many kinds for an unreadable file)
        raise UserInputError(f"cannot read the photo ({type(exc).__name__}: {exc})", file=path,
                             expected="a raw file LibRaw reads, or a JPEG/PNG/TIFF image") from None


def _selected_photos(dataset: Path, wanted: tuple[str, ...]) -> list[Path]:
    photos = dataset_files(dataset)["photos"]  # refuses a dataset without photos, naming photos/
    if not wanted:
        return photos
    by_name = {p.name: p for p in photos}
    missing = [n for n in wanted if n not in by_name]
    if missing:
        raise UserInputError(f"no such photo in the dataset: {', '.join(missing)}", file=dataset / "photos",
                             field="--photo", expected=f"one of {', '.join(sorted(by_name))}")
    return [by_name[n] for n in dict.fromkeys(wanted)]


def _check_sizes(dataset: Path, scene_source: str, scene_size: tuple[int, int]) -> tuple[int, int]:
    """The photos' common size, checked against each other and against the scene camera's aspect."""
    files = dataset_files(dataset)
    photos = files["photos"]
    sizes = {p: photo_size(p) for p in photos}
    _check_raws(files["brackets"] + files["boards"])
    first = photos[0]
    for path, size in sizes.items():
        if size != sizes[first]:
            raise UserInputError(f"the photos differ in size: {first.name} is {sizes[first][0]} x {sizes[first][1]}",
                                 file=path, expected="photos of one camera at one size", got=f"{size[0]} x {size[1]}")
    width, height = sizes[first]
    aspect, scene_aspect = width / height, scene_size[0] / scene_size[1]
    if abs(aspect / scene_aspect - 1) > ASPECT_TOLERANCE:
        raise UserInputError(f"the photos ({width} x {height}, aspect {aspect:.3f}) do not match the scene's camera "
                             f"({scene_size[0]} x {scene_size[1]}, aspect {scene_aspect:.3f})", file=scene_source,
                             field="camera.resolution", expected=f"the photos' aspect within {ASPECT_TOLERANCE:.0%}, "
                             f"e.g. [{width}, {height}]", got=f"{first}: {width} x {height}")
    return width, height


def _check_raws(paths: list[Path]) -> None:
    """Refuse a damaged raw among the bracket frames and board views before any stage runs (the calibration stage
    would decode it only after the plan and the tables, which can take hours)."""
    for path in paths:
        if is_raw(path):
            check_raw_file(path)


def run_scene_text(spec: SceneSpec, table_preset: str) -> str:
    """The scene file the run uses: ``spec``'s with every computed table at ``table_preset``
    (a table the scene names by path is kept) and structure and table paths absolute."""
    data = tomllib.loads(spec.text)
    sections: tuple[tuple[str, tuple[CDSpec | GratingSpec, ...]], ...] = (("cd", spec.cds), ("grating", spec.gratings))
    for key, elements in sections:
        for entry, element in zip(data.get(key, []), elements, strict=True):
            structure = element.structure
            if structure not in BUILTIN_STRUCTURES and Path(structure).exists():
                structure = os.path.abspath(structure)
            entry["structure"] = structure
            if "path" in element.table:
                entry["table"] = {"path": os.path.abspath(element.table["path"])}
            else:
                entry["table"] = dict(element.table) | {"preset": table_preset}
    header = f"# {spec.source}, as `workbench verify` uses it (tables at the {table_preset} preset)\n"
    return header + tomli_w.dumps(data)


# ---------------------------------------------------------------- stages


def _stage_plan(run: Run) -> dict:
    def work(folder: Path) -> dict[str, Any]:
        plan = plan_scene(load_scene(run.scene))
        atomic_write_text(folder / "plan.json", json.dumps(plan.to_json(), indent=2, default=_json_default) + "\n")
        atomic_write_text(folder / "plan.txt", format_plan(plan) + "\n")
        return {"rcwa_needed": plan.rcwa_needed, "elements": [
            {"element": e.key, "tables": e.tables, "fraction": e.fraction, "seconds_whole": e.seconds_whole,
             "megabytes_whole": e.megabytes_whole} for e in plan.elements]}

    return run_stage(run, "plan", {"scene.toml": run.scene}, {}, SECONDS_PLAN, work)


def _elements(spec: SceneSpec) -> list[tuple[str, CDSpec | GratingSpec]]:
    return [(f"cd[{i}]", cd) for i, cd in enumerate(spec.cds)] + [(f"grating[{i}]", g) for i, g in enumerate(spec.gratings)]


def _stage_tables(run: Run, plan: dict) -> dict:
    spec = load_scene(run.scene)
    plans = {where: table_plan(element, where, str(run.scene)) for where, element in _elements(spec)}
    estimate = sum(e["seconds_whole"] for e in plan.get("result", {}).get("elements", [])
                   if not plans[e["element"]].path.exists())

    def work(folder: Path) -> dict[str, Any]:
        tables = {}
        for where, table in tqdm(plans.items(), desc="tables", unit="table", disable=not run.settings.progress):
            if table.settings is None:  # a table the scene names: checked when the scene is built
                tables[where] = {"path": str(table.path), "key": table.key, "named": True}
                continue
            report = build_table(table.structure, table.settings, table.path, progress=run.settings.progress, force=True,
                                 executor=run.executor)
            tables[where] = {"path": str(table.path), "key": table.key, "cached": report.cached,
                             "chunks_computed": report.chunks_computed, "seconds": report.seconds}
        atomic_write_text(folder / "tables.json", json.dumps(tables, indent=2) + "\n")
        return {"tables": tables}

    def intact(folder: Path) -> bool:  # the cache may have been cleared since
        return all(p.path.exists() for p in plans.values())

    return run_stage(run, "tables", {"scene.toml": run.scene}, {"preset": PRESETS[run.settings.preset]["tables"]},
                     estimate, work, intact)


def _dataset_inputs(dataset: Path) -> dict[str, Path]:
    files: dict[str, Path] = {}
    for sub in DATASET_FOLDERS:
        folder = dataset / sub
        if folder.is_dir():
            files |= {f"{sub}/{p.name}": p for p in sorted(folder.iterdir()) if p.is_file()}
    return files


def _stage_calibration(run: Run) -> dict:
    files = _dataset_inputs(run.dataset)
    options: dict[str, Any] = {}
    if run.settings.board is not None:
        options["board"] = tuple(run.settings.board)
    if run.settings.square_mm is not None:
        options["square_mm"] = run.settings.square_mm
    estimate = SECONDS_CALIBRATION_BASE + SECONDS_PER_POSE * len(dataset_files(run.dataset)["photos"])

    def work(folder: Path) -> dict[str, Any]:
        record = calibrate_dataset(run.dataset, run.scene, folder, progress=run.settings.progress,
                                   executor=run.executor, **options)
        return {"residuals_rms_px": {name: r.get("rms_px") for name, r in record["residuals"].items()},
                "intrinsics_rms_px": record.get("intrinsics", {}).get("rms_px")}

    return run_stage(run, "calibration", files | {"scene.toml": run.scene},
                     {k: list(v) if isinstance(v, tuple) else v for k, v in options.items()}, estimate, work,
                     lambda folder: (folder / "calibration.json").is_file())


def _stage_fit(run: Run) -> dict:
    calibration = run.root / "calibration" / "calibration.json"
    brackets = _bracket_frames(run.dataset)
    renders = run.root / "render"
    inputs = ({f"photos/{p.name}": p for p in run.photos} | {f"brackets/{p.name}": p for p in brackets}
              | {"calibration.json": calibration, "scene.toml": run.scene}
              | {f"scenes/{p.name}": run.root / "calibration" / "scenes" / f"{p.stem}.toml" for p in run.photos}
              | {f"render/{p.stem}.exr": renders / f"{p.stem}.exr" for p in run.photos})

    def work(folder: Path) -> dict[str, Any]:
        spec = load_scene(run.scene)
        if spec.fit is None or not spec.fit.free:
            atomic_write_text(folder / NOT_FITTED, "the scene has no CD or no free [fit] parameter: nothing to fit\n")
            return {"verdict": None, "rerender": False, "reason": "nothing to fit"}
        try:
            record = _fit(run, FitInputs(run.dataset, str(run.scene), calibration, folder,
                                         tuple(p.name for p in run.photos), renders=renders))
        except UserInputError as error:  # the photos do not constrain the scene (too few band edges): say so, go on
            atomic_write_text(folder / NOT_FITTED, error.reason + "\n")
            return {"verdict": None, "rerender": False, "reason": error.reason}
        judged = Verdict.from_json(record["verdict"], folder / "scene_fit.json")
        rerender = judged.outcome is Outcome.MODEL
        if rerender:
            for photo in run.photos:
                calibrated = run.root / "calibration" / "scenes" / f"{photo.stem}.toml"
                write_fitted_scene(spec, spec.fit, np.asarray(record["values"]), folder / "scenes",
                                   f"{photo.name}: the calibrated camera with the scene fit's values",
                                   base=tomllib.loads(calibrated.read_text()), name=f"{photo.stem}.toml",
                                   structures=folder)
        return {"verdict": judged.outcome.value, "rerender": rerender,
                "residuals_before_px": record["residuals_before_px"], "residuals_after_px": record["residuals_after_px"],
                "seconds": record["timings"]["total"]}

    return run_stage(run, "fit", inputs, {}, SECONDS_FIT, work,
                     lambda folder: (folder / "scene_fit.json").is_file() or (folder / NOT_FITTED).is_file())


def _fit(run: Run, inputs: FitInputs) -> dict[str, Any]:
    """reports.scene_fit.job.run_fit, here or as one task on the run's executor: the fit is joint over the photos
    (one least-squares problem over every photo's band edges), so it stays one task."""
    if run.executor is None:
        return run_fit(inputs)
    return run.executor.submit(_fit_task, inputs).result()


def _fit_task(inputs: FitInputs) -> dict[str, Any]:
    """run_fit on a dask worker with BLAS on every core of its machine: dask starts workers with one BLAS thread
    (OPENBLAS_NUM_THREADS=1), and the fit's forward model, numpy on every photo's band edges, then took 2.4 times
    as long (168 s against 70 s for the draft dataset's two photos, 2 cores)."""
    from threadpoolctl import threadpool_limits  # deferred: only a cluster's fit needs it

    with threadpool_limits(limits=os.cpu_count(), user_api="blas"):
        return run_fit(inputs)


def _stage_render(run: Run) -> dict:
    """Each photo's calibrated scene (the scene file through its fitted camera)."""
    return _render_stage(run, "render", {p.stem: run.root / "calibration" / "scenes" / f"{p.stem}.toml"
                                         for p in run.photos})


def _stage_rerender(run: Run) -> dict:
    """Each photo's fitted scene after the verdict ``model`` (the re-render that confirms the fit); none otherwise."""
    fitted = run.record["stages"].get("fit", {}).get("result", {}).get("rerender")
    return _render_stage(run, "rerender", {p.stem: run.root / "fit" / "scenes" / f"{p.stem}.toml" for p in run.photos}
                         if fitted else {})


def _render_stage(run: Run, stage: str, scenes: dict[str, Path]) -> dict:
    """Render ``scenes`` ({output stem: scene file}) into RUN/``stage``/STEM.exr at the run's settings."""
    s = run.settings
    settings = {"preset": s.preset, "spp": s.render_spp, "target": s.render_target, "seed": s.seed,
                "integrator": s.integrator, "mode": s.mode, "resolution": list(run.size)}
    frame_spp = FLOOR_SPP if s.render_target else s.render_spp
    estimate = len(scenes) * (SECONDS_RENDER_LOAD + SECONDS_PER_SAMPLE * run.size[0] * run.size[1] * frame_spp
                              + (SECONDS_TARGET_CD if s.render_target else 0.0))

    def work(folder: Path) -> dict[str, Any]:
        renders = {}
        for name, scene in scenes.items():
            info = render(scene, folder / f"{name}.exr", preset=s.preset, spp=None if s.render_target else s.render_spp,
                          resolution=run.size, integrator=s.integrator, mode=s.mode, seed=s.seed, progress=s.progress,
                          executor=run.executor, force=True, target=s.render_target)  # the staging folder is the run's
            _point_sidecar_at(folder / f"{name}.json", run.root / stage)
            renders[name] = {"exr": f"{name}.exr", "seconds": info["seconds_total"],
                             "served": info.get("served", False), "resumed_passes": info.get("resumed_passes", 0)}
        return {"renders": renders}

    return run_stage(run, stage, {f"scenes/{k}.toml": p for k, p in scenes.items()}, settings, estimate, work,
                     lambda folder: all((folder / f"{n}.exr").is_file() for n in scenes))


def _point_sidecar_at(sidecar: Path, final_folder: Path) -> None:
    """The render's sidecar names where its images will be once the stage is moved into place, not the staging
    folder they were written in (renderer.render reads neither path back)."""
    info = json.loads(sidecar.read_text())
    for key in ("output", "preview"):
        if isinstance(info.get(key), str):
            info[key] = str(final_folder / Path(info[key]).name)
    atomic_write_text(sidecar, json.dumps(info, indent=2))


def _bracket_frames(dataset: Path) -> tuple[Path, ...]:
    """DATASET/brackets' files: each report fills its photo's clipped highlights from the darker frames that show
    the photo's view (reports.compare.exposure_merge checks that pixel by pixel and leaves the others out)."""
    folder = dataset / "brackets"
    return tuple(sorted(p for p in folder.iterdir() if p.is_file())) if folder.is_dir() else ()


def _stage_report(run: Run) -> dict:
    renders = {p.stem: run.root / "render" / f"{p.stem}.exr" for p in run.photos}
    refitted = run.record["stages"].get("rerender", {}).get("result", {}).get("renders") or {}
    fitted = {stem: run.root / "rerender" / f"{stem}.exr" for stem in refitted}
    calibration = run.root / "calibration" / "calibration.json"
    fitted_record = run.root / "fit" / "scene_fit.json"
    scene_fit = fitted_record if fitted_record.is_file() else None  # none: nothing to fit, or too few edges
    brackets = _bracket_frames(run.dataset)
    inputs = ({f"photos/{p.name}": p for p in run.photos} | {f"render/{k}.exr": p for k, p in renders.items()}
              | {f"rerender/{k}.exr": p for k, p in fitted.items()}
              | {f"brackets/{p.name}": p for p in brackets} | {"calibration.json": calibration, "scene.toml": run.scene}
              | ({"scene_fit.json": scene_fit} if scene_fit is not None else {})
              | {f"studies/{k}/{f.name}": f for k, folder in enumerate(run.settings.study_folders)
                 for f in study_figures((folder,))})

    common = _ReportCommon(calibration, brackets, scene_fit, run.settings.study_folders)

    def photo_args(photo: Path, folder: Path) -> tuple:
        return (common, photo, renders[photo.stem], run.scene, fitted.get(photo.stem),
                run.root / "fit" / "fitted_scene.toml", folder / photo.stem)

    def work(folder: Path) -> dict[str, Any]:
        if run.executor is None:
            return {"reports": {photo.name: _report_photo(*photo_args(photo, folder)) for photo in
                                tqdm(run.photos, desc="report", unit="photo", disable=not run.settings.progress)}}
        futures = {photo.name: run.executor.submit(_report_photo, *photo_args(photo, folder)) for photo in run.photos}
        return {"reports": {name: future.result() for name, future in futures.items()}}

    return run_stage(run, "report", inputs, {}, SECONDS_PER_REPORT * (len(renders) + len(fitted)), work,
                     lambda folder: all((folder / p.stem / "report.html").is_file() for p in run.photos))


@dataclass(frozen=True)
class _ReportCommon:
    """What every photo's report of a run reads besides its photo and render."""

    calibration: Path
    brackets: tuple[Path, ...]
    scene_fit: Path | None
    studies: tuple[Path, ...]

    def report(self, photo: Path, render_path: Path, scene: Path, out: Path, before: dict | None = None) -> dict:
        if (out / "report.html").is_file():  # finished by a killed run with these inputs (written after report.json)
            return json.loads((out / "report.json").read_text())
        return build_report(Inputs(photo, render_path, self.calibration, str(scene), out, brackets=self.brackets,
                                   brackets_strict=False, scene_fit=self.scene_fit, offsets_nominal_scene=before,
                                   studies=self.studies))


def _report_photo(common: _ReportCommon, photo: Path, nominal_render: Path, scene: Path, fitted_render: Path | None,
                  fitted_scene: Path, out: Path) -> dict[str, Any]:
    """One photo's report (here, or as a task on a dask worker, which writes into the run's staging folder): against
    its render, or after a re-render against the fitted scene's, with the nominal one's in ``out``/nominal."""
    if fitted_render is None:
        report = common.report(photo, nominal_render, scene, out)
    else:
        nominal = common.report(photo, nominal_render, scene, out / "nominal")
        report = common.report(photo, fitted_render, fitted_scene, out, nominal["fringe_offset_px"])
    return {"html": f"{photo.stem}/report.html", "fringe_offset_px": report["fringe_offset_px"],
            "verdict": report.get("verdict", {}).get("verdict"), "problems": report.get("problems", []),
            "seconds": report["seconds"]}


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


# ---------------------------------------------------------------- the command


def verify(dataset: str | Path, scene: str | Path, out: str | Path, settings: VerifySettings | None = None, *,
           force: bool = False) -> dict[str, Any]:
    """Run (or resume, or skip) every stage; returns run.json's content with its ``summary``."""
    settings = settings or VerifySettings()
    if settings.preset not in PRESETS:
        raise UserInputError("unknown preset", field="--preset", expected=f"one of {sorted(PRESETS)}", got=settings.preset)
    if settings.spp is not None and settings.spp < 1:
        raise UserInputError("must be at least 1", field="--spp", got=settings.spp)
    dataset, root = Path(dataset), Path(out)
    spec = load_scene(scene)
    photos = _selected_photos(dataset, settings.photos)
    study_figures(settings.study_folders)  # a missing folder or one without figures is refused before anything runs
    size = _check_sizes(dataset, spec.source, (spec.camera.model.width, spec.camera.model.height))
    identity = {"dataset": str(dataset.resolve()), "scene": str(scene)}
    with run_lock(root):
        return _verify_locked(root, dataset, scene, spec, photos, size, identity, settings, force)


def _verify_locked(root: Path, dataset: Path, scene: str | Path, spec: SceneSpec, photos: list[Path], size: tuple[int, int],
                   identity: dict[str, str], settings: VerifySettings, force: bool) -> dict[str, Any]:
    run = Run(root, open_run(root, identity, settings, force), dataset, photos, size, settings)
    atomic_write_text(run.scene, run_scene_text(spec, PRESETS[settings.preset]["tables"]))
    run.save()
    for line in stage_needs(dataset_files(dataset)):  # what each stage has to work with, before it runs
        _say(run, line)
    started = time.perf_counter()
    try:
        run.executor = _executor(settings.scheduler, settings.workers)
        plan = _stage_plan(run)
        _stage_tables(run, plan)
        _stage_calibration(run)
        _stage_render(run)
        _stage_fit(run)
        _stage_rerender(run)
        _stage_report(run)
    except BaseException as exc:
        run.record.update(status="failed", error=f"{type(exc).__name__}: {exc}")
        run.save()
        raise
    finally:
        if run.executor is not None:
            run.executor.__exit__(None, None, None)
    if (root / ".staging").is_dir() and not any((root / ".staging").iterdir()):
        (root / ".staging").rmdir()
    run.record.update(status="finished", seconds=round(time.perf_counter() - started, 2), summary=run_summary(run))
    run.record.pop("error", None)
    if settings.preset == "paper" and size != PAPER_RESOLUTION:
        run.record["summary"]["notes"] = [f"the photos are {size[0]} x {size[1]}, not the paper's "
                                          f"{PAPER_RESOLUTION[0]} x {PAPER_RESOLUTION[1]}: rendered at the photos' size"]
    run.record["summary"]["index"] = str(write_run_index(root, run.record))
    run.save()
    return run.record


def _executor(scheduler: str | None, workers: int | None) -> DaskExecutor | None:
    """The run's dask executor: the scheduler at ``scheduler``, a LocalCluster of ``workers`` processes, or none."""
    if not scheduler and not workers:
        return None
    return DaskExecutor(scheduler, workers).__enter__()


def run_summary(run: Run) -> dict[str, Any]:
    """Where the reports are, each photo's fringe offsets, the calibration's residuals."""
    calibration = json.loads((run.root / "calibration" / "calibration.json").read_text())
    reports = run.record["stages"]["report"]["result"]
    photos = {}
    for name, r in reports["reports"].items():
        residual = calibration["residuals"].get(name, {})
        photos[name] = {"report": str(run.root / "report" / r["html"]), "fringe_offset_px": r["fringe_offset_px"],
                        "pose_rms_px": residual.get("rms_px"), "pose_median_abs_px": residual.get("median_abs_px")}
    fit = run.record["stages"].get("fit", {}).get("result", {})
    return {"photos": photos, "intrinsics_rms_px": calibration.get("intrinsics", {}).get("rms_px"),
            "scene_fit": {"verdict": fit.get("verdict"), "rerendered": fit.get("rerender"),
                          "record": str(run.root / "fit" / "scene_fit.json")},
            "seconds_per_stage": {k: v.get("seconds", 0.0) if not v.get("skipped") else 0.0
                                  for k, v in run.record["stages"].items()}}


def format_summary(record: dict[str, Any]) -> str:
    """The summary printed at the end of a run."""
    summary = record["summary"]
    stages = record["stages"]
    lines = ["stages: " + ", ".join(f"{k} {'skipped' if v.get('skipped') else format(v.get('seconds', 0), '.1f') + ' s'}"
                                    for k, v in stages.items())]
    intrinsics = summary.get("intrinsics_rms_px")
    lines.append("calibration: board views " + (f"RMS {intrinsics:.3f} px" if intrinsics is not None else "not used"))
    fit = summary.get("scene_fit") or {}
    if fit.get("verdict"):
        lines.append(f"scene fit: verdict {fit['verdict']}" + (" (the fitted scene re-rendered)" if fit.get("rerendered")
                                                              else "") + f"; {fit['record']}")
    for name, p in summary["photos"].items():
        fo = p["fringe_offset_px"] or {}
        offsets = (f"fringe offset photo-render median {fo['median']:.2f} px, p95 {fo['p95']:.2f} px "
                   f"({fo.get('count')} band edges)" if fo.get("median") is not None
                   else "fringe offset: no band edge seen in both photo and render")
        pose = f"pose residual RMS {p['pose_rms_px']:.3f} px" if p.get("pose_rms_px") is not None else "no pose residual"
        lines.append(f"{name}: {pose}; {offsets}")
        lines.append(f"  report: {p['report']}")
    if summary.get("index"):
        lines.append(f"index of the run: {summary['index']}")
    lines += [f"note: {n}" for n in summary.get("notes", [])]
    return "\n".join(lines)

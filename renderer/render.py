"""``workbench render``: a scene to linear camera RGB (EXR), a PNG preview and a JSON sidecar.

Rendering runs in passes (different seeds, averaged: unbiased); after each pass the
running sums (of the passes and of their squares) are saved atomically beside the output, so
an interrupted render resumes from its finished passes when the same command runs again.
A render of two or more passes also writes ``NAME.variance.exr``: per pixel, the variance
of the rendered mean from the spread between passes (s^2 / n, s^2 the passes' sample
variance), through the same warp and exposure (squared). The warp is bilinear at about one
plan pixel per output pixel (renderer.camera.CameraModel.pinhole_plan), so the warped
variance is right for sums over regions (each plan pixel's weights add to about 1), which
is what reports.compare.regions uses; for one pixel alone it can overstate up to 4 times. The sidecar records the request's
key, the EXR's SHA-256, the settings, versions, timings and the efficiency tables used.
As with tables, the same request on a finished render is served at once, and a different
one at the same path needs ``force``.

``target="report"`` (``--target report``) renders progressively instead: each region until
what the report measures there is good enough, the CD as its own crop of the film
(renderer.render_target; its sums and decisions saved after each pass, so it resumes the
same way); the sidecar's ``spp`` is then the frame's (every pixel has at least that many)
and ``target`` records each region's spp and noise.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from renderer import render_target
from renderer.mitsuba_scene import cropped_sensor, scene_dict
from renderer.preview import PreviewRequest, white_balance, write_preview
from renderer.regions import region_masks
from renderer.render_target import CROP_SEED_OFFSET, PASS_SPP, TARGETS, State, Target, Window, crop_path, target_settings
from renderer.scene import SceneSpec, load_scene
from renderer.tables import table_keys
from renderer.variant import set_variant
from workbench.core.cache import reading as cache_reading
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write as _atomic
from workbench.core.files import atomic_write_npz, atomic_write_text, exclusive_output, file_sha256
from workbench.core.timing import timed
from workbench.core.version import __version__ as workbench_version
from workbench.core.version import versions

PRESETS: dict[str, dict[str, Any]] = {"draft": {"spp": 256, "pass_spp": 64},
                                      "paper": {"spp": 2045, "pass_spp": 128, "resolution": (978, 734)}}
SIDECAR_FORMAT = "workbench-render"
MIN_PASSES = 4  # where spp allows: the variance between passes (variance_path) then has 3 degrees of freedom per pixel
WORKER_SCENES = 2  # scenes a worker keeps loaded (render_pass): a targeted render's frame and crop
_WORKER_SCENES: dict[str, Any] = {}  # on a worker: loaded Mitsuba scenes by their pass settings' hash, oldest first


def with_resolution(spec: SceneSpec, resolution: tuple[int, int] | None) -> SceneSpec:
    """The scene's camera at another resolution (intrinsics scaled with the image)."""
    if resolution is None:
        return spec
    cam = spec.camera.model
    sx, sy = resolution[0] / cam.width, resolution[1] / cam.height
    model = replace(cam, width=resolution[0], height=resolution[1], fx=cam.fx * sx, fy=cam.fy * sy,
                    cx=(cam.cx + 0.5) * sx - 0.5, cy=(cam.cy + 0.5) * sy - 0.5)
    return replace(spec, camera=replace(spec.camera, model=model))


def render_pass(spec: SceneSpec, pass_spp: int, integrator: str, mode: str, pass_seed: int, plan: bool = True,
                crop: Window | None = None, threads: int | None = None) -> np.ndarray:
    """One pass on a dask worker: build the scene there (tables come from the cache; the last
    WORKER_SCENES scenes stay loaded, so a render's next passes only render) and render (only the
    film's ``crop`` window, where given: renderer.render_target). ``threads``: the client's Dr.Jit
    thread count, which sets the order the film sums in (renderer.variant): with it, a pass is the
    same bytes on any worker as in the client's own render."""
    set_variant()
    import drjit as dr  # deferred: after set_variant, and start-up time
    import mitsuba as mi

    if threads is not None and dr.thread_count() != threads:
        dr.set_thread_count(threads)
    key = hashlib.sha256(json.dumps([spec.text, table_keys(spec), spec.camera.model.width, spec.camera.model.height,
                                     pass_spp, integrator, mode, plan, None if crop is None else crop.to_json()],
                                    default=str).encode()).hexdigest()
    if key not in _WORKER_SCENES:
        scene_d, _ = scene_dict(mi, spec, spp=pass_spp, integrator=integrator, mode=mode, plan=plan)
        if crop is not None:
            scene_d["sensor"] = cropped_sensor(scene_d["sensor"], (crop.x, crop.y), (crop.width, crop.height))
        while len(_WORKER_SCENES) >= WORKER_SCENES:
            _WORKER_SCENES.pop(next(iter(_WORKER_SCENES)))
        _WORKER_SCENES[key] = mi.load_dict(scene_d)
    # Mitsuba's stub types seed as UInt32; a Python int is what it takes at run time
    return np.array(mi.render(_WORKER_SCENES[key], seed=pass_seed))  # type: ignore[arg-type]


def client_threads() -> int:
    """The Dr.Jit thread count here (after set_variant), which every pass sent to a worker renders with."""
    import drjit as dr  # deferred: start-up time

    return int(dr.thread_count())


@dataclass(frozen=True)
class _Passes:
    """A render's passes: the scene, the settings each pass renders it with, and how many."""

    spec: SceneSpec
    pass_spp: int
    integrator: str
    mode: str
    seed: int
    plan: bool
    count: int


def render(scene: str | Path, out: str | Path, *, preset: str = "draft", spp: int | None = None,
           resolution: tuple[int, int] | None = None, integrator: str = "path", mode: str = "improved",
           seed: int = 0, progress: bool = True, executor=None, force: bool = False, plan: bool = True,
           target: str | None = None, preview: PreviewRequest | None = None) -> dict:
    """Render ``scene``; with ``executor`` (workbench.core.executor.DaskExecutor) the passes run on a
    dask.distributed cluster, each with its own seed, averaged here: the result is the
    same as a local render with the same seed.

    Like ``workbench rcwa table``: when ``out`` holds the finished render of the same
    request (scene, tables, settings, seed, version; the EXR unchanged since), it is
    served at once (``info["served"]``); a different render or other files at ``out``
    (the EXR, its PNG preview or JSON sidecar) are replaced only with ``force``; an
    interrupted render of the same request resumes (``info["resumed_passes"]``).

    ``plan`` (the default): the tables are planned for this camera (renderer.trace.planner,
    renderer.mitsuba_scene.scene_dict); False builds whole tables, for comparison.
    ``target`` ("report"): each region sampled to what the report measures there
    (renderer.render_target), the preset's spp the frame's cap; None: ``spp`` samples everywhere.
    ``preview``: the PNG preview's white level (renderer.preview; default: the image's own); a
    served render whose preview used another level has its preview written again.
    """
    spp, pass_spp, spec, out = _checked_request(scene, out, preset, spp, resolution, integrator, mode, seed, target)
    with exclusive_output(out, "render"), cache_reading():  # one render per --out; no cache clear under it
        return _render(spec, out, preset, spp, pass_spp, integrator, mode, seed, progress, executor, force, plan, target,
                       preview or PreviewRequest())


def _render(spec: SceneSpec, out: Path, preset: str, spp: int, pass_spp: int, integrator: str, mode: str, seed: int,
            progress: bool, executor, force: bool, plan: bool, target: str | None, preview: PreviewRequest) -> dict:
    """``render`` under its output's lock."""
    goal = target_settings(preset, spp) if target is not None else None
    pass_spp = PASS_SPP if goal is not None else pass_spp
    passes = _Passes(spec, pass_spp, integrator, mode, seed, plan, math.ceil(spp / pass_spp))
    key = _request_key(spec, spp, pass_spp, integrator, mode, seed, plan, goal)
    partial = out.with_name(out.name + ".partial.npz")
    finished = _finished_render(out, key)
    if finished is not None:
        return _refresh_preview(out, spec, finished, preview)
    for damaged in render_target.discard_damaged_checkpoints(partial):
        print(f"note: {damaged}: a damaged checkpoint (not a readable .npz) was removed; its passes are rendered again",
              file=sys.stderr)
    _refuse_to_overwrite(out, partial, key, force)
    variant = set_variant()
    import mitsuba as mi  # deferred: after set_variant, and start-up time

    started = time.perf_counter()
    scene_d, built = scene_dict(mi, spec, spp=pass_spp, integrator=integrator, mode=mode, plan=plan, progress=progress)
    if goal is None:
        mean, variance, done, pass_seconds, extra = _fixed_passes(mi, scene_d, passes, partial, key, executor, progress)
    else:
        mean, variance, done, pass_seconds, extra = _targeted_passes(mi, scene_d, built, passes, goal, partial, key,
                                                                     executor, progress)
        passes = replace(passes, count=extra["target"]["frame_spp"] // pass_spp)
    lit, shown = _write_images(mi, out, spec, built["plan"], mean, variance, preview)
    info = _sidecar(out, key, preset, passes, variant, built["tables"], time.perf_counter() - started, pass_seconds,
                    done) | extra | {"lit_pixel_fraction": lit, "preview_settings": shown}
    atomic_write_text(out.with_suffix(".json"), json.dumps(info, indent=2))
    partial.unlink(missing_ok=True)
    crop_path(partial).unlink(missing_ok=True)  # a targeted render's crop sums
    return info | {"served": False}


def _fixed_passes(mi, scene_d: dict, passes: _Passes, partial: Path, key: str, executor, progress: bool):
    """``passes.count`` passes everywhere (resumed from ``partial``): (mean, variance of the mean or
    None, passes resumed, seconds per pass, nothing more for the sidecar), in the plan's pixels."""
    total, total_sq, done = _resume(partial, key)
    bar = tqdm(total=passes.count, initial=done, unit="pass", disable=not progress, desc=f"render {passes.spec.name}")
    pass_seconds = []
    for p, (image, seconds) in _pass_images(mi, scene_d, passes, done, executor):
        image = np.asarray(image, np.float64)
        total = image if total is None else total + image
        total_sq = image**2 if total_sq is None else total_sq + image**2
        atomic_write_npz(partial, total=total, total_sq=total_sq, done=p + 1, key=key)
        pass_seconds.append(seconds)
        bar.update(1)
    bar.close()
    return total / passes.count, _mean_variance(total, total_sq, passes.count), done, pass_seconds, {}


def _targeted_passes(mi, scene_d: dict, built: dict, passes: _Passes, goal: dict, partial: Path, key: str, executor,
                     progress: bool):
    """The targeted render's passes (renderer.render_target), resumed from ``partial``: as _fixed_passes,
    with the sidecar's ``target`` record and the passes of frame and crop together."""
    spec = passes.spec
    target = Target.build(spec.camera.model, built["plan"], region_masks(spec), goal)
    state = State.load(partial, key)
    resumed = state.passes
    bar = tqdm(initial=resumed, unit="pass", disable=not progress, desc=f"render {spec.name} (target report)")
    pass_seconds: list[float] = []
    render_passes = _target_pass_images(mi, scene_d, passes, target, executor, pass_seconds)
    render_target.sample(state, target, render_passes, lambda: state.save(partial), lambda: bar.update(1))
    bar.close()
    mean, variance, _count = state.merged(target.window, target.weight)
    extra = {"target": render_target.record(state, target, goal), "passes": state.passes}
    return mean[..., :3], variance[..., :3], resumed, pass_seconds, extra


def _target_pass_images(mi, scene_d: dict, passes: _Passes, target: Target, executor, seconds: list[float]):
    """renderer.render_target's RenderPasses: the frame's or the crop's passes by index, each with its
    own seed (module docstring of renderer.render_target), here or on ``executor``'s workers."""
    window = target.window
    loaded = mi.load_dict(scene_d) if executor is None else None
    threads = client_threads()
    crop = None
    if executor is None and window is not None:
        cropped = cropped_sensor(scene_d["sensor"], (window.x, window.y), (window.width, window.height))
        crop = mi.load_dict(dict(cropped, sampler=dict(cropped["sampler"], sample_count=target.crop_pass_spp)))

    def run(kind: str, indices: range) -> Iterator[np.ndarray]:
        seeds = [pass_seed(passes.seed, i if kind == "frame" else CROP_SEED_OFFSET + i) for i in indices]
        if executor is None:
            sensor = crop if kind == "crop" else 0
            for s in seeds:
                image, took = timed(lambda s=s: np.array(mi.render(loaded, sensor=sensor, seed=s)))
                seconds.append(took)
                yield image
            return
        spp, where = (target.crop_pass_spp, window) if kind == "crop" else (passes.pass_spp, None)
        futures = [executor.submit(timed, render_pass, passes.spec, spp, passes.integrator, passes.mode, s, passes.plan,
                                   where, threads, alone=True) for s in seeds]
        for future in futures:
            image, took = future.result()
            seconds.append(took)
            yield image
    return run


def _write_images(mi, out: Path, spec: SceneSpec, plan, mean: np.ndarray, variance: np.ndarray | None,
                  preview: PreviewRequest) -> tuple[float, dict]:
    """The EXR, its preview and (with a variance) the variance EXR, from the plan's mean and the variance of that mean;
    returns the share of the EXR's pixels that are lit (float32, as written) and the preview's settings."""
    rgb = spec.camera.model.warp(mean, plan) * spec.camera.exposure
    if not np.all(np.isfinite(rgb)):
        raise RuntimeError("the render produced non-finite values")
    out.parent.mkdir(parents=True, exist_ok=True)
    written = rgb.astype(np.float32)
    _atomic(out, lambda tmp: mi.Bitmap(written, mi.Bitmap.PixelFormat.RGB).write(str(tmp)))
    shown = _write_png(out, spec, rgb, preview)
    if variance is not None:
        variance = np.maximum(spec.camera.model.warp(variance, plan), 0.0) * spec.camera.exposure**2
        _atomic(variance_path(out), lambda tmp: mi.Bitmap(variance.astype(np.float32), mi.Bitmap.PixelFormat.RGB).write(str(tmp)))
    return lit_fraction(written), shown


def _write_png(out: Path, spec: SceneSpec, rgb: np.ndarray, preview: PreviewRequest) -> dict:
    """The render's PNG preview beside ``out``, written atomically; returns its settings for the sidecar."""
    shown: dict = {}
    gains = white_balance(spec.light.spectrum, spec.camera.sensitivities)
    _atomic(out.with_suffix(".png"), lambda tmp: shown.update(write_preview(rgb, tmp, gains, preview)))
    return shown


def _refresh_preview(out: Path, spec: SceneSpec, info: dict, preview: PreviewRequest) -> dict:
    """A served render's preview, written again when this request's white level differs from the one it used."""
    used = info.get("preview_settings") or {}
    if preview.white_level is None or used.get("white_level") == preview.white_level:
        return info
    set_variant()
    import mitsuba as mi  # deferred: after set_variant, and start-up time

    rgb = np.array(mi.Bitmap(str(out)), dtype=np.float64)[..., :3]
    shown = _write_png(out, spec, rgb, preview)
    record = {k: v for k, v in info.items() if k != "served"} | {"preview_settings": shown}
    atomic_write_text(out.with_suffix(".json"), json.dumps(record, indent=2))
    return record | {"served": True}


def variance_path(out: str | Path) -> Path:
    """Where the render at ``out`` keeps its per-pixel variance (module docstring)."""
    out = Path(out)
    return out.with_name(out.stem + ".variance.exr")


def _mean_variance(total: np.ndarray, total_sq: np.ndarray, count: int) -> np.ndarray | None:
    """The variance of the mean of ``count`` passes, from their sum and sum of squares; None for one pass."""
    if count < 2:
        return None
    mean = total / count
    return np.maximum(total_sq / count - mean**2, 0.0) * count / (count - 1) / count


def _pass_images(mi, scene_d: dict, passes: _Passes, done: int, executor) -> Iterator[tuple[int, tuple[np.ndarray, float]]]:
    """(pass, (image, seconds)) for the passes after the ``done`` ones, here or on ``executor``'s workers."""
    if executor is None:
        loaded = mi.load_dict(scene_d)
        # Mitsuba's stub types seed as UInt32; a Python int is what it takes at run time
        return ((p, timed(lambda p=p: np.array(mi.render(loaded, seed=pass_seed(passes.seed, p)))))
                for p in range(done, passes.count))
    threads = client_threads()
    futures = {p: executor.submit(timed, render_pass, passes.spec, passes.pass_spp, passes.integrator, passes.mode,
                                  pass_seed(passes.seed, p), passes.plan, None, threads, alone=True)
               for p in range(done, passes.count)}
    return ((p, futures[p].result()) for p in range(done, passes.count))


def _sidecar(out: Path, key: str, preset: str, passes: _Passes, variant: str, tables: list[str], seconds: float,
             pass_seconds: list[float], resumed: int) -> dict:
    """The render's JSON sidecar: the request, the EXR's SHA-256, the settings, versions, timings, the camera."""
    spec, model = passes.spec, passes.spec.camera.model
    return {
        "format": SIDECAR_FORMAT, "request_key": key, "output_sha256": file_sha256(out),
        "scene": spec.name, "scene_source": spec.source, "scene_sha256": hashlib.sha256(spec.text.encode()).hexdigest(),
        "output": str(out), "preview": str(out.with_suffix(".png")), "preset": preset,
        "variance": str(variance_path(out)) if passes.count > 1 else None,
        "spp": passes.count * passes.pass_spp, "passes": passes.count,
        "resolution": [model.width, model.height], "integrator": passes.integrator, "mode": passes.mode,
        "seed": passes.seed, "variant": variant, "planned_tables": passes.plan, "tables": tables,
        "seconds_total": seconds,
        "seconds_per_pass": pass_seconds, "resumed_passes": resumed,
        "versions": versions("mitsuba", "drjit", "numpy"),
        "units": "linear camera RGB (integral of radiance x camera sensitivity, times exposure)",
        "camera": {"width": model.width, "height": model.height, "fx": model.fx,
                   "fy": model.fy, "cx": model.cx, "cy": model.cy,
                   "dist": list(model.dist), "world_to_camera": model.world_to_camera.tolist(),
                   "sensitivities": spec.camera.sensitivities, "exposure": spec.camera.exposure,
                   "response": spec.camera.response.to_json()},
    }


def pass_seed(seed: int, index: int) -> int:
    """Pass ``index``'s Mitsuba seed: spread apart per render seed, inside Mitsuba's unsigned
    32 bits (``--seed`` reaches 2**32 - 1; beyond 32 bits Mitsuba's sampler raises)."""
    return (seed * 100_003 + index) % 2**32


def lit_fraction(image: np.ndarray) -> float:
    """The share of pixels that received any light (a channel above 0)."""
    return float(np.mean(np.any(image > 0, axis=-1)))


def black_warning(info: dict) -> str | None:
    """A warning line when no pixel of the render received light (None otherwise, and for a
    sidecar written before the count was kept)."""
    if info.get("lit_pixel_fraction", 1.0) > 0:
        return None
    return (f"warning: {info['output']} is black: no pixel received light. Check the scene's light (its power_w and "
            "where it points) and that the camera is inside the box and not facing a wall at point-blank range")


def summary(info: dict) -> str:
    """One line for the command line: what was written, or that a finished render was served."""
    size = f"{info['resolution'][0]}x{info['resolution'][1]}, {info['spp']} spp" + (" (the frame)" if info.get("target") else "")
    if info.get("served"):
        return (f"{info['output']}: up to date (request {info['request_key'][:12]}): the finished identical render "
                f"({size}, {info['seconds_total']:.1f} s when it was made) is served; nothing rendered")
    resumed = (f"; resumed after {info['resumed_passes']} of {info['passes']} passes finished earlier"
               if info.get("resumed_passes") else "")
    noise = f", the passes' variance {info['variance']}" if info.get("variance") else ""
    shown = info.get("preview_settings")
    preview = f" (white level {shown['white_level']:.4g})" if shown else ""
    return (f"wrote {info['output']} (linear camera RGB), {info['preview']}{preview}{noise} and the sidecar "
            f"{info['output'][:-4]}.json: {size}, {info['seconds_total']:.1f} s ({info['variant']}){resumed}"
            + (f"; {target_summary(info['target'])}" if info.get("target") else ""))


def target_summary(record: dict) -> str:
    """What a targeted render reached (renderer.render_target.record), in one clause."""
    cd = record["regions"].get("cd")
    walls = record["walls"]
    parts = [f"target report: the frame {record['frame_spp']} spp"]
    if cd is not None:
        edges = (f"edges {cd['edge_sigma_px']:.3f} px (goal {cd['goal_edge_sigma_px']} px"
                 f"{'' if cd['met'] else ', not reached at the cap'})" if cd["edge_pixels"] else "no band edge seen")
        parts.append(f"the CD {cd['spp'][1]} spp, {edges}")
    if math.isfinite(walls["scale_relative_std"]):
        parts.append(f"the walls' scale {100 * walls['scale_relative_std']:.3f} % (goal {100 * walls['goal']:.1f} %"
                     f"{'' if walls['met'] else ', not reached at the cap'})")
    return ", ".join(parts)


FILM_BYTES_PER_PIXEL = 160  # Mitsuba's film (RGBA and weight, float32), the passes' sums and squares, mean and
# variance (three float64 channels each), the EXR and preview buffers: measured peaks stay below this
FILM_MEMORY_FRACTION = 0.5


def check_film_memory(resolution: tuple[int, int], field: str, total_bytes: int | None = None,
                      file: str | None = None) -> None:
    """Refuse a frame whose buffers would not fit in memory, before Mitsuba allocates them (issue 46,
    cause 1: ``--resolution 100000x100000`` ran until memory ran out), with the estimate in the message."""
    if total_bytes is None:
        try:
            total_bytes = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            return
    width, height = resolution
    need = width * height * FILM_BYTES_PER_PIXEL
    if need > FILM_MEMORY_FRACTION * total_bytes:
        raise UserInputError(f"a {width} x {height} frame needs about {need / 2**30:.0f} GiB of buffers, more than half of "
                             f"this machine's {total_bytes / 2**30:.0f} GiB", field=field, file=file,
                             expected=f"at most about {int(FILM_MEMORY_FRACTION * total_bytes / FILM_BYTES_PER_PIXEL / 1e6)} "
                                      "megapixels")


def _checked_request(scene: str | Path, out: str | Path, preset: str, spp: int | None,
                     resolution: tuple[int, int] | None, integrator: str, mode: str,
                     seed: int, target: str | None = None) -> tuple[int, int, SceneSpec, Path]:
    """Every argument checked before anything is built or written: (spp, spp per pass, scene, out)."""
    if target is not None and target not in TARGETS:
        raise UserInputError("unknown target", field="--target", expected=f"one of {list(TARGETS)}", got=target)
    if target is not None and spp is not None:
        raise UserInputError("--spp renders that many samples everywhere; --target chooses them per region",
                             field="--spp", expected="--spp N or --target report, not both", got=spp)
    if preset not in PRESETS:
        raise UserInputError("unknown preset", field="--preset", expected=f"one of {sorted(PRESETS)}", got=preset)
    if integrator not in ("path", "direct"):
        raise UserInputError("unknown integrator", field="--integrator", expected="path or direct", got=integrator)
    if mode not in ("paper", "improved"):
        raise UserInputError("unknown mode", field="--mode", expected="paper or improved", got=mode)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise UserInputError("must be a non-negative integer", field="--seed", got=seed)
    settings = dict(PRESETS[preset])
    spp = int(settings["spp"] if spp is None else spp)
    if spp < 1:
        raise UserInputError("must be at least 1", field="--spp", got=spp)
    out = Path(out)
    if out.suffix.lower() != ".exr":
        raise UserInputError("the output must be an OpenEXR file", field="--out", expected="a path ending in .exr",
                             got=str(out))
    if out.is_dir():
        raise UserInputError("is a folder, not a file", field="--out", expected="a path ending in .exr", got=str(out))
    spec = with_resolution(load_scene(scene), resolution or settings.get("resolution"))
    check_film_memory((spec.camera.model.width, spec.camera.model.height), "--resolution" if resolution else "camera.resolution",
                      file=None if resolution else spec.source)
    # MIN_PASSES passes where spp allows: their spread is the render's noise (variance_path)
    return spp, min(settings["pass_spp"], max(1, math.ceil(spp / MIN_PASSES))), spec, out


def _request_key(spec: SceneSpec, spp: int, pass_spp: int, integrator: str, mode: str, seed: int, plan: bool,
                 target: dict | None = None) -> str:
    """What a render is of: scene text, image size, sampling (a targeted render's goals and caps),
    seed, the tables' own request keys (their content, wherever the cache is; planned for the
    camera or whole) and the workbench version.
    """
    request = {"scene": spec.text, "w": spec.camera.model.width, "h": spec.camera.model.height, "spp": spp,
               "pass": pass_spp, "integrator": integrator, "mode": mode, "seed": seed, "tables": table_keys(spec),
               "planned_tables": plan, "version": workbench_version}
    if target is not None:  # absent for fixed renders: their keys (and served renders) stay as they were
        request["target"] = target
    return hashlib.sha256(json.dumps(request, sort_keys=True).encode()).hexdigest()


def _outputs(out: Path) -> list[Path]:
    return [out, out.with_suffix(".png"), out.with_suffix(".json")]


def _all_outputs(out: Path, info: dict) -> list[Path]:
    """The files a finished render wrote: its EXR, preview, sidecar and (with two passes or more) the variance."""
    return _outputs(out) + ([variance_path(out)] if info.get("variance") else [])


def _read_sidecar(out: Path) -> dict | None:
    try:
        info = json.loads(out.with_suffix(".json").read_text())
    except (OSError, ValueError):
        return None
    return info if isinstance(info, dict) and info.get("format") == SIDECAR_FORMAT else None


def described_render(out: str | Path) -> dict | None:
    """The sidecar of the render at ``out`` if it describes that very EXR (same SHA-256), else None."""
    out = Path(out)
    info = _read_sidecar(out)
    if info is None or not out.is_file() or file_sha256(out) != info.get("output_sha256"):
        return None
    return info


def _finished_render(out: Path, key: str) -> dict | None:
    """The sidecar of the finished render of this very request at ``out``, if its images are
    all there and the EXR is the one it describes.
    """
    info = described_render(out)
    if info is None or info.get("request_key") != key or not all(p.is_file() for p in _all_outputs(out, info)):
        return None
    return info | {"served": True}


def _refuse_to_overwrite(out: Path, partial: Path, key: str, force: bool) -> None:
    """A different render at ``out`` is replaced only with ``force``, files no render wrote (no sidecar
    describes them) never; an interrupted render of this request may carry on.
    """
    present = [p for p in _outputs(out) + [variance_path(out)] if p.exists()]
    if not present or _resume(partial, key)[2] > 0 or State.load(partial, key).passes > 0:
        return  # (a fixed render's saved passes, or a targeted one's)
    info = _read_sidecar(out)
    if info is None:  # not even --force replaces what no render wrote (issue 46, cause 3)
        raise UserInputError("the output already holds files that no render of this workbench described: "
                             + ", ".join(p.name for p in present), file=out,
                             expected="a new path, or those files moved away (--force replaces only a render's own files)")
    if force:
        return
    if out.is_file() and file_sha256(out) != info.get("output_sha256"):
        what = "a render whose EXR was changed since it was written"
    elif info.get("request_key") == key:
        return  # this request, with a part missing (a deleted preview): rendered again
    else:
        what = (f"a different render (of {info.get('scene_source', 'another scene')}, {info.get('spp')} spp, "
                f"seed {info.get('seed')})")
    raise UserInputError(f"the output already holds {what}", file=out,
                         expected="a new path, the same request, or --force to replace it")


def _resume(partial: Path, key: str):
    try:
        with np.load(partial) as d:
            if str(d["key"]) == key:
                return d["total"], d["total_sq"], int(d["done"])
    except render_target.DAMAGED_NPZ:
        pass
    return None, None, 0





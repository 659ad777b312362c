"""``workbench render``: a scene to linear camera RGB (EXR), a PNG preview and a JSON sidecar.

Rendering runs in passes (different seeds, averaged: unbiased); after each pass the
running sum is saved atomically beside the output, so an interrupted render resumes from
its finished passes when the same command runs again. The sidecar records the settings,
versions, timings and the efficiency tables used (with their content keys).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from renderer.scene import SceneSpec, load_scene
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write as _atomic
from workbench.core.timing import timed

PRESETS = {"draft": {"spp": 256, "pass_spp": 64}, "paper": {"spp": 2045, "pass_spp": 128, "resolution": (978, 734)}}


def with_resolution(spec: SceneSpec, resolution: tuple[int, int] | None) -> SceneSpec:
    """The scene's camera at another resolution (intrinsics scaled with the image)."""
    if resolution is None:
        return spec
    cam = spec.camera.model
    sx, sy = resolution[0] / cam.width, resolution[1] / cam.height
    model = replace(cam, width=resolution[0], height=resolution[1], fx=cam.fx * sx, fy=cam.fy * sy,
                    cx=(cam.cx + 0.5) * sx - 0.5, cy=(cam.cy + 0.5) * sy - 0.5)
    return replace(spec, camera=replace(spec.camera, model=model))


def render_pass(spec: SceneSpec, pass_spp: int, integrator: str, mode: str, pass_seed: int) -> np.ndarray:
    """One pass on a dask worker: build the scene there (tables come from the cache) and render."""
    from renderer.variant import set_variant

    set_variant()
    import mitsuba as mi

    from renderer.build import scene_dict

    scene_d, _ = scene_dict(mi, spec, spp=pass_spp, integrator=integrator, mode=mode)
    return np.array(mi.render(mi.load_dict(scene_d), seed=pass_seed))


def render(scene: str | Path, out: str | Path, *, preset: str = "draft", spp: int | None = None,
           resolution: tuple[int, int] | None = None, integrator: str = "path", mode: str = "improved",
           seed: int = 0, progress: bool = True, executor=None) -> dict:
    """Render ``scene``; with ``executor`` (workbench.core.executor.DaskExecutor) the passes run on a
    dask.distributed cluster, each with its own seed, averaged here: the result is the
    same as a local render with the same seed."""
    from tqdm import tqdm

    from renderer.variant import set_variant

    if preset not in PRESETS:
        raise UserInputError("unknown preset", field="--preset", expected=f"one of {sorted(PRESETS)}", got=preset)
    if integrator not in ("path", "direct"):
        raise UserInputError("unknown integrator", field="--integrator", expected="path or direct", got=integrator)
    if mode not in ("paper", "improved"):
        raise UserInputError("unknown mode", field="--mode", expected="paper or improved", got=mode)
    settings = dict(PRESETS[preset])
    spp = int(settings["spp"] if spp is None else spp)
    if spp < 1:
        raise UserInputError("must be at least 1", field="--spp", got=spp)
    spec = with_resolution(load_scene(scene), resolution or settings.get("resolution"))
    out = Path(out)
    if out.suffix.lower() != ".exr":
        raise UserInputError("the output must be an OpenEXR file", field="--out", expected="a path ending in .exr", got=str(out))
    variant = set_variant()
    import mitsuba as mi

    from renderer.build import scene_dict

    started = time.perf_counter()
    pass_spp = min(spp, settings["pass_spp"])
    passes = math.ceil(spp / pass_spp)
    scene_d, built = scene_dict(mi, spec, spp=pass_spp, integrator=integrator, mode=mode)
    key = hashlib.sha256(json.dumps({"scene": spec.text, "w": spec.camera.model.width, "h": spec.camera.model.height,
                                     "spp": spp, "pass": pass_spp, "integrator": integrator, "mode": mode, "seed": seed,
                                     "tables": built["tables"]}, sort_keys=True).encode()).hexdigest()
    partial = out.with_name(out.name + ".partial.npz")
    total, done = _resume(partial, key)
    bar = tqdm(total=passes, initial=done, unit="pass", disable=not progress, desc=f"render {spec.name}")
    pass_seconds = []
    if executor is None:
        loaded = mi.load_dict(scene_d)
        images = ((p, timed(lambda p=p: np.array(mi.render(loaded, seed=seed * 100_003 + p)))) for p in range(done, passes))
    else:
        futures = {p: executor.submit(timed, render_pass, spec, pass_spp, integrator, mode, seed * 100_003 + p) for p in range(done, passes)}
        images = ((p, futures[p].result()) for p in range(done, passes))
    for p, (image, seconds) in images:
        total = image if total is None else total + image
        _atomic_npz(partial, total=total, done=p + 1, key=key)
        pass_seconds.append(seconds)
        bar.update(1)
    bar.close()
    mean = total / passes
    rgb = spec.camera.model.warp(mean, built["plan"]) * spec.camera.exposure
    if not np.all(np.isfinite(rgb)):
        raise RuntimeError("the render produced non-finite values")
    out.parent.mkdir(parents=True, exist_ok=True)
    _atomic(out, lambda tmp: mi.Bitmap(rgb.astype(np.float32), mi.Bitmap.PixelFormat.RGB).write(str(tmp)))
    preview = out.with_suffix(".png")
    _atomic(preview, lambda tmp: _write_preview(rgb, tmp))
    sidecar = out.with_suffix(".json")
    info = {
        "scene": spec.name, "scene_source": spec.source, "scene_sha256": hashlib.sha256(spec.text.encode()).hexdigest(),
        "output": str(out), "preview": str(preview), "preset": preset, "spp": passes * pass_spp, "passes": passes,
        "resolution": [spec.camera.model.width, spec.camera.model.height], "integrator": integrator, "mode": mode,
        "seed": seed, "variant": variant, "tables": built["tables"], "seconds_total": time.perf_counter() - started,
        "seconds_per_pass": pass_seconds, "resumed_passes": done,
        "versions": {"mitsuba": mi.__version__, "python": platform.python_version(), "numpy": np.__version__},
        "units": "linear camera RGB (integral of radiance x camera sensitivity, times exposure)",
        "camera": {"width": spec.camera.model.width, "height": spec.camera.model.height, "fx": spec.camera.model.fx,
                   "fy": spec.camera.model.fy, "cx": spec.camera.model.cx, "cy": spec.camera.model.cy,
                   "dist": list(spec.camera.model.dist), "world_to_camera": spec.camera.model.world_to_camera.tolist(),
                   "sensitivities": spec.camera.sensitivities, "exposure": spec.camera.exposure,
                   "response": spec.camera.response.to_json()},
    }
    _atomic(sidecar, lambda tmp: tmp.write_text(json.dumps(info, indent=2)))
    partial.unlink(missing_ok=True)
    return info


def _write_preview(rgb: np.ndarray, path: Path) -> None:
    import cv2

    scale = np.percentile(rgb, 99.5) or 1.0
    srgb = np.clip(rgb / scale, 0, 1) ** (1 / 2.2)
    if not cv2.imwrite(str(path), (srgb[..., ::-1] * 255 + 0.5).astype(np.uint8)):
        raise OSError(f"cannot write {path}")


def _resume(partial: Path, key: str):
    try:
        with np.load(partial) as d:
            if str(d["key"]) == key:
                return d["total"], int(d["done"])
    except (OSError, KeyError, ValueError):
        pass
    return None, 0


def _atomic_npz(path: Path, **arrays) -> None:
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
    _atomic(path, write)



"""``workbench synth``: a folder that looks like real camera files, with the truth beside it.

Layout (other tools read it): ``DIR/photos/*.dng`` (views of the scene), ``DIR/truth.json``
(never inside the photos). The hidden camera is the scene's camera perturbed by a seeded
random offset (pose by a few degrees and centimetres, field of view by a few degrees,
principal point, distortion), with the exposure and the light power off by a factor:
what the paper could not control. truth.json holds the camera (width, height, fx, fy,
cx, cy, dist [k1, k2, p1, p2, k3] in OpenCV's model, world_to_camera per photo in
OpenCV's axes, metres), the exposure time per file, the response curve, the light-power
scale and the sensor model. Same seed, same bytes.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from datasets_synthetic.dng import DngMetadata, write_dng
from datasets_synthetic.sensor import SensorModel
from workbench.errors import UserInputError
from workbench.files import atomic_write_text

PRESETS = {"draft": {"resolution": (320, 240), "spp": 64}, "full": {"resolution": (978, 734), "spp": 512}}
MARKER = "workbench-synthetic-dataset"


def hidden_camera(camera, rng: np.random.Generator):
    """The scene camera perturbed: rotation up to ~2 deg, translation ~2 cm, FOV ~2 deg,
    principal point ~1 % of the width, a mild distortion."""
    from scipy.spatial.transform import Rotation

    T = camera.world_to_camera.copy()
    dR = Rotation.from_rotvec(np.radians(rng.normal(0.0, 1.0, 3))).as_matrix()
    origin = -T[:3, :3].T @ T[:3, 3] + rng.normal(0.0, 0.01, 3)
    R = dR @ T[:3, :3]
    T[:3, :3], T[:3, 3] = R, -R @ origin
    fov = 2 * math.degrees(math.atan(0.5 * camera.width / camera.fx)) + rng.normal(0.0, 1.0)
    f = 0.5 * camera.width / math.tan(math.radians(fov) / 2)
    return dataclasses.replace(
        camera, world_to_camera=T, fx=f, fy=f * (1 + rng.normal(0, 0.002)),
        cx=camera.cx + rng.normal(0, 0.01 * camera.width), cy=camera.cy + rng.normal(0, 0.01 * camera.height),
        dist=(float(rng.normal(-0.08, 0.03)), float(rng.normal(0.02, 0.01)), float(rng.normal(0, 5e-4)),
              float(rng.normal(0, 5e-4)), 0.0),
    )


def _prepare_folder(out: Path, force: bool) -> None:
    if out.exists() and any(out.iterdir()):
        marker = out / "truth.json"
        ours = marker.exists() and MARKER in marker.read_text()[:200]
        if not force:
            raise UserInputError("the output folder is not empty" + (" (it holds another dataset)" if ours else ""),
                                 file=out, expected="a new or empty folder, or --force to replace the dataset")
        import shutil

        shutil.rmtree(out)
    (out / "photos").mkdir(parents=True, exist_ok=True)


def synth(scene: str, out: str | Path, *, seed: int = 0, preset: str = "draft", force: bool = False) -> dict:
    if preset not in PRESETS:
        raise UserInputError("unknown preset", field="--preset", expected=f"one of {sorted(PRESETS)}", got=preset)
    from renderer.fit import FitRenderer
    from renderer.render import with_resolution
    from renderer.scene import load_scene

    spec = load_scene(scene)
    if spec.camera is None:  # pragma: no cover - the scene format requires a camera
        raise UserInputError("the scene has no camera", field="camera")
    out = Path(out)
    _prepare_folder(out, force)
    rng = np.random.default_rng(seed)
    p = PRESETS[preset]
    spec = with_resolution(spec, p["resolution"])
    truth_cam = hidden_camera(spec.camera.model, rng)
    exposure_scale = float(np.exp(rng.normal(0.0, 0.3)))
    light_scale = float(np.exp(rng.normal(0.0, 0.3)))
    sensor = SensorModel()
    hidden = dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, model=truth_cam))
    fit = FitRenderer(hidden, resolution=p["resolution"], spp=p["spp"])
    fit.set(light_power_scale=light_scale)
    rgb = fit.render(seed=seed)
    exposure_s = _auto_exposure(rgb, sensor) * exposure_scale
    raw = sensor.capture(rgb, exposure_s, rng)
    name = "view0.dng"
    write_dng(out / "photos" / name, raw, DngMetadata(cfa_pattern=sensor.cfa_pattern, black_level=sensor.black_level,
                                                       white_level=sensor.white_level, exposure_time_s=exposure_s))
    truth = {
        "format": MARKER, "seed": seed, "preset": preset, "scene": spec.name,
        "camera": {"width": truth_cam.width, "height": truth_cam.height, "fx": truth_cam.fx, "fy": truth_cam.fy,
                   "cx": truth_cam.cx, "cy": truth_cam.cy, "dist": list(truth_cam.dist),
                   "world_to_camera": {name: truth_cam.world_to_camera.tolist()}},
        "exposure_time_s": {name: exposure_s},
        "response": spec.camera.response.to_json(),
        "light_power_scale": light_scale,
        "sensor": dataclasses.asdict(sensor) | {"white_level": sensor.white_level},
    }
    atomic_write_text(out / "truth.json", json.dumps(truth, indent=2))
    return truth


def _auto_exposure(rgb: np.ndarray, sensor: SensorModel) -> float:
    """An exposure time that puts the 99th percentile at 70 % of the raw range (before the
    seeded 'off by a factor' the photographer could not control)."""
    level = np.percentile(rgb.max(axis=-1), 99.0)
    usable = sensor.white_level - sensor.black_level
    return float(0.7 * usable / (sensor.gain * sensor.electrons_per_unit * max(level, 1e-12)))

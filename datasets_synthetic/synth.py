"""``workbench synth``: a folder that looks like real camera files, with the truth beside it.

Layout (other tools read it; DESIGN.md section 6)::

    DIR/photos/view*.dng          views of the scene (view0: the scene's camera, hidden offset applied;
                                  view1...: the same camera moved around the scene)
    DIR/brackets/ev*.dng, *.jpg   exposure brackets of view0, 1 EV apart, RAW+JPEG as a camera writes them
    DIR/calibration/board*.dng    a checkerboard held in the box in several poses, seen by view0's camera
                                  with its flash on
    DIR/truth.json                the truth (never inside the photos)
    DIR/run.json                  settings, versions and timings of the run

The hidden camera is the scene's camera perturbed by a seeded random offset (pose by a
few degrees and centimetres, field of view by a few degrees, principal point,
distortion), with the exposure and the light power off by a factor, and a non-linear
response in its JPEGs: what the paper could not control. truth.json holds ``camera``
(width, height, fx, fy, cx, cy, dist [k1, k2, p1, p2, k3] in OpenCV's model, and
``world_to_camera`` in OpenCV's axes, metres, for every file by file name), the
``exposure_time_s`` of every file, ``response`` (the JPEGs' curve as samples of normalised
irradiance to normalised value), ``light_power_scale``, ``board`` (type, inner_corners,
square_size_m, and ``board_to_world`` per calibration file), ``brackets`` and the
``sensor`` model. File names are unique across the folders. Same seed, same bytes.

The calibration set is made for OpenCV to recover the hidden intrinsics (issue 6: the
board found in every view, fx, fy, cx, cy within 0.5 %, the distortion close; checked by
tests/datasets_synthetic/test_synth.py). What that took, measured: the principal point is
the weak part (with p1, p2 fitted, its standard deviation is about five times the
focal lengths'), so the board is pushed into the image's corners and edges and tilted all
round (board.py), which needs light from the camera's side: a flash (a point light at
the camera's centre, ``board.flash`` in truth.json) lights every pose, where the
ceiling light alone lit only boards turned up towards it. The draft preset renders at
640 x 480: at 320 x 240 the corners' noise left the principal point uncertain by
0.4 % (one standard deviation, cv2.calibrateCameraExtended) even with the best corner
refinement found; at 640 x 480 with 16 spp per board view (the flash's direct light
is clean, so few samples do) it is 0.25 %, and the run takes about as long as 320 x 240
with 64 spp per board view did (about a minute here).
"""

from __future__ import annotations

import dataclasses
import json
import math
import platform
import time
from pathlib import Path

import numpy as np

from datasets_synthetic.board import BOARD_KEY, Checkerboard, corners_visible, sample_pose
from datasets_synthetic.dng import DngMetadata, write_dng
from datasets_synthetic.jpeg import develop, hidden_response, write_jpeg
from datasets_synthetic.sensor import SensorModel
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text

PRESETS = {
    "draft": {"resolution": (640, 480), "spp": 64, "views": 2, "calibration_views": 20, "calibration_spp": 16},
    "full": {"resolution": (978, 734), "spp": 512, "views": 3, "calibration_views": 15, "calibration_spp": 64},
}
BRACKET_EV = (-2, -1, 0, 1, 2)
FLASH_KEY = "calibration_flash"
FLASH_W_PER_SR = 20.0
MARKER = "workbench-synthetic-dataset"
MAKE, MODEL, ISO = "Workbench", "Synthetic RGGB", 100


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


def orbit(camera, yaw_deg: float, pitch_deg: float):
    """The same camera moved around the point its optical axis meets the floor (y = 0), or
    the point 1 m ahead when it looks level: a second photograph of the same scene."""
    from scipy.spatial.transform import Rotation

    cam_to_world = np.linalg.inv(camera.world_to_camera)
    origin, axis = cam_to_world[:3, 3], cam_to_world[:3, 2]
    distance = -origin[1] / axis[1] if axis[1] < -0.05 else 1.0
    pivot = origin + distance * axis
    right = cam_to_world[:3, 0]
    turn = Rotation.from_rotvec(np.radians(yaw_deg) * np.array([0.0, 1.0, 0.0])) * Rotation.from_rotvec(np.radians(pitch_deg) * right)
    moved = np.eye(4)
    moved[:3, :3] = turn.as_matrix() @ cam_to_world[:3, :3]
    moved[:3, 3] = pivot + turn.apply(origin - pivot)
    return dataclasses.replace(camera, world_to_camera=np.linalg.inv(moved))


def _prepare_folder(out: Path, force: bool) -> None:
    if out.exists() and any(out.iterdir()):
        marker = out / "truth.json"
        ours = marker.exists() and MARKER in marker.read_text()[:200]
        if not force:
            raise UserInputError("the output folder is not empty" + (" (it holds another dataset)" if ours else ""),
                                 file=out, expected="a new or empty folder, or --force to replace the dataset")
        import shutil

        shutil.rmtree(out)
    for sub in ("photos", "brackets", "calibration"):
        (out / sub).mkdir(parents=True, exist_ok=True)


@dataclasses.dataclass
class _Shot:
    """What truth.json says of one file."""
    exposure_time_s: float
    world_to_camera: np.ndarray


class _Writer:
    """Writes raw frames (DNG, and the camera's JPEG where asked) and collects their truth."""

    def __init__(self, out: Path, sensor: SensorModel, response) -> None:
        self.out, self.sensor, self.response = out, sensor, response
        self.shots: dict[str, _Shot] = {}

    def capture(self, folder: str, stem: str, rgb: np.ndarray, exposure_s: float, camera, rng, jpeg: bool = False) -> np.ndarray:
        raw = self.sensor.capture(rgb, exposure_s, rng)
        meta = DngMetadata(cfa_pattern=self.sensor.cfa_pattern, black_level=self.sensor.black_level,
                           white_level=self.sensor.white_level, exposure_time_s=exposure_s, iso=ISO, make=MAKE, model=MODEL)
        write_dng(self.out / folder / f"{stem}.dng", raw, meta)
        self.shots[f"{stem}.dng"] = _Shot(exposure_s, camera.world_to_camera)
        if jpeg:
            write_jpeg(self.out / folder / f"{stem}.jpg", develop(raw, self.sensor, self.response),
                       exposure_time_s=exposure_s, iso=ISO, make=MAKE, model=MODEL)
            self.shots[f"{stem}.jpg"] = _Shot(exposure_s, camera.world_to_camera)
        return raw


def synth(scene: str, out: str | Path, *, seed: int = 0, preset: str = "draft", force: bool = False,
          progress: bool = True) -> dict:
    """Write the dataset for ``scene`` into ``out``; returns the truth (also in truth.json)."""
    if preset not in PRESETS:
        raise UserInputError("unknown preset", field="--preset", expected=f"one of {sorted(PRESETS)}", got=preset)
    from tqdm import tqdm

    from renderer.fit import FitRenderer
    from renderer.render import with_resolution
    from renderer.scene import load_scene

    started = time.perf_counter()
    spec = load_scene(scene)
    if spec.camera is None:  # pragma: no cover - the scene format requires a camera
        raise UserInputError("the scene has no camera", field="camera")
    out = Path(out)
    _prepare_folder(out, force)
    p = PRESETS[preset]
    rng_camera, rng_views, rng_noise, rng_board = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(4))
    spec = with_resolution(spec, p["resolution"])
    camera = hidden_camera(spec.camera.model, rng_camera)
    exposure_scale = float(np.exp(rng_camera.normal(0.0, 0.3)))
    light_scale = float(np.exp(rng_camera.normal(0.0, 0.3)))
    response = hidden_response(rng_camera)
    sensor = SensorModel()
    writer = _Writer(out, sensor, response)
    hidden = dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, model=camera))
    bar = tqdm(total=p["views"] + p["calibration_views"], desc="synth renders", unit="frame", disable=not progress)
    timings: dict[str, float] = {}

    tick = time.perf_counter()
    fit = FitRenderer(hidden, resolution=p["resolution"], spp=p["spp"])
    fit.set(light_power_scale=light_scale)
    view0 = None
    for k in range(p["views"]):
        view_camera = camera if k == 0 else orbit(camera, rng_views.choice([-1, 1]) * rng_views.uniform(6, 12),
                                                   rng_views.uniform(-3, 3))
        fit.set(camera=view_camera)
        rgb = fit.render(seed=seed * 1000 + k)
        exposure_s = _auto_exposure(rgb, sensor) * exposure_scale
        writer.capture("photos", f"view{k}", rgb, exposure_s, view_camera, rng_noise)
        if k == 0:
            view0 = (rgb, exposure_s)
        bar.update()
    timings["photos_s"] = time.perf_counter() - tick

    tick = time.perf_counter()
    rgb, exposure_s = view0
    for ev in BRACKET_EV:
        writer.capture("brackets", f"ev{ev:+d}", rgb, exposure_s * 2.0**ev, camera, rng_noise, jpeg=True)
    timings["brackets_s"] = time.perf_counter() - tick

    tick = time.perf_counter()
    board = Checkerboard()
    poses = _calibration_set(hidden, camera, board, p, light_scale, seed, writer, rng_board, rng_noise, bar)
    timings["calibration_s"] = time.perf_counter() - tick
    bar.close()

    truth = {
        "format": MARKER, "seed": seed, "preset": preset, "scene": spec.name,
        "camera": {"width": camera.width, "height": camera.height, "fx": camera.fx, "fy": camera.fy,
                   "cx": camera.cx, "cy": camera.cy, "dist": list(camera.dist),
                   "world_to_camera": {name: shot.world_to_camera.tolist() for name, shot in writer.shots.items()}},
        "exposure_time_s": {name: shot.exposure_time_s for name, shot in writer.shots.items()},
        "response": response.to_json() | {"applies_to": "brackets/*.jpg (the DNGs are linear)"},
        "light_power_scale": light_scale,
        "exposure_scale": exposure_scale,
        "board": board.to_json() | {"board_to_world": {name: pose.tolist() for name, pose in poses.items()},
                                    "flash": {"at": "the camera's centre", "intensity_w_per_sr": FLASH_W_PER_SR,
                                              "spectrum": spec.light.spectrum}},
        "brackets": {"of": "view0.dng", "ev": list(BRACKET_EV)},
        "sensor": dataclasses.asdict(sensor) | {"white_level": sensor.white_level},
    }
    atomic_write_text(out / "truth.json", json.dumps(truth, indent=2))
    timings["total_s"] = time.perf_counter() - started
    _write_run_record(out, scene, seed, preset, p, timings)
    return truth


def _calibration_set(hidden, camera, board: Checkerboard, p: dict, light_scale: float, seed: int, writer: _Writer,
                     rng_board, rng_noise, bar) -> dict[str, np.ndarray]:
    """Board views from view0's camera, its flash on: seeded poses in which nothing hides the board."""
    from renderer.fit import FitRenderer

    import mitsuba as mi

    first = sample_pose(board, camera, rng_board, view=0)
    fit = FitRenderer(hidden, resolution=(camera.width, camera.height), spp=p["calibration_spp"],
                      extra_objects={BOARD_KEY: board.mitsuba_shape(mi, first), FLASH_KEY: _flash(hidden, camera)})
    fit.set(light_power_scale=light_scale)
    poses: dict[str, np.ndarray] = {}
    pose = first
    for i in range(p["calibration_views"]):
        while True:
            fit.move(BOARD_KEY, board.shape_matrix(pose))
            if corners_visible(mi, fit.scene, board, pose, camera):
                break
            pose = sample_pose(board, camera, rng_board, view=i)
        rgb = fit.render(seed=seed * 1000 + 500 + i)
        name = f"board{i:02d}"
        writer.capture("calibration", name, rgb, _auto_exposure(rgb, writer.sensor), camera, rng_noise)
        poses[f"{name}.dng"] = pose
        if i + 1 < p["calibration_views"]:
            pose = sample_pose(board, camera, rng_board, view=i + 1)
        bar.update()
    return poses


def _flash(spec, camera) -> dict:
    """The photographer's flash: a point light at the camera's centre with the scene light's
    spectrum and radiant intensity FLASH_W_PER_SR (W/sr), so that it outshines the ceiling
    light on the board (80 W/m^2 at 0.5 m, against about 25 W/m^2 at 35 cm from the
    10 W ceiling light)."""
    from renderer.build import irregular, light_spectrum

    wl, s = light_spectrum(spec.light.spectrum)
    centre = np.linalg.inv(camera.world_to_camera)[:3, 3]
    return {"type": "point", "position": centre.tolist(), "intensity": irregular(wl, s * FLASH_W_PER_SR / np.trapezoid(s, wl))}


def _write_run_record(out: Path, scene: str, seed: int, preset: str, settings: dict, timings: dict) -> None:
    import mitsuba

    from workbench.core.version import __version__ as workbench_version

    record = {"command": "workbench synth", "scene": scene, "seed": seed, "preset": preset, "settings": settings,
              "timings": timings, "versions": {"workbench": workbench_version, "mitsuba": mitsuba.__version__,
                                               "numpy": np.__version__, "python": platform.python_version()}}
    atomic_write_text(out / "run.json", json.dumps(record, indent=2, default=list))


def _auto_exposure(rgb: np.ndarray, sensor: SensorModel) -> float:
    """An exposure time that puts the 99th percentile at 70 % of the raw range (before the
    seeded 'off by a factor' the photographer could not control)."""
    level = np.percentile(rgb.max(axis=-1), 99.0)
    usable = sensor.white_level - sensor.black_level
    return float(0.7 * usable / (sensor.gain * sensor.electrons_per_unit * max(level, 1e-12)))

"""``workbench synth``: a folder that looks like real camera files, with the truth beside it.

Layout (other tools read it; DESIGN.md section 6)::

    DIR/photos/view*.dng          views of the scene (view0: the scene's camera, hidden offset applied;
                                  view1...: the same camera moved around the scene)
    DIR/brackets/ev*.dng, *.jpg   exposure brackets of view0, RAW+JPEG as a camera writes them: 1 EV apart from
                                  ev-2 to ev+2 (for the response curve), and ev-4, ev-6 for the CD's bright orders
    DIR/calibration/board*.dng    a checkerboard held in the box in several poses, seen by view0's camera
                                  with its flash on
    DIR/calibration/board.json    what that board is, as a photographer would note it (board_views.BOARD_FORMAT:
                                  kind, inner corners, square size in mm); ``calibrate DATASET`` reads it
    DIR/truth.json                the truth (never inside the photos)
    DIR/run.json                  settings, versions and timings of the run, and every file it wrote
                                  (size, SHA-256): what ``--force`` may replace, and nothing else

Safety: everything is checked before anything is written; the dataset is made in a work
folder beside DIR (``.DIR.synth-partial``) and moved into place when complete, so an
interrupted run leaves DIR as it was; the work folder keeps the finished renders (as
.npy), from which the same command resumes with the same bytes.

The hidden camera is the scene's camera perturbed by a seeded random offset (pose by a
few degrees and centimetres, field of view by a few degrees, principal point,
distortion), with the exposure and the light power off by a factor, and a non-linear
response in its JPEGs: what the paper could not control. truth.json holds ``camera``
(width, height, fx, fy, cx, cy, dist [k1, k2, p1, p2, k3] in OpenCV's model, and
``world_to_camera`` in OpenCV's axes, metres, for every file by file name), the
``exposure_time_s`` of every file, ``response`` (the JPEGs' curve as samples of normalised
irradiance to normalised value), ``light_power_scale``, ``board`` (type, inner_corners,
square_size_m, and ``board_to_world`` per calibration file), ``brackets`` and the
``sensor`` model (with the DNGs' colour tags), and the ``render_seed`` of the renders'
Monte Carlo (the seed unless synth is given another). File names are unique across the
folders. Same seeds, same bytes.

Every DNG carries the colour tags a raw developer needs (``colour_tags``): AsShotNeutral,
the camera's RGB of a white diffuse surface under the scene light's spectrum (what a
photographer's grey card would read), so that developing with the camera's white balance
shows the white walls white (not green: the camera's green channel is the most
sensitive); and ColorMatrix1, XYZ to camera RGB under D65 fitted to the camera's spectral
sensitivities. Calibration reads neither (it works in camera RGB).

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
with 64 spp per board view did (about a minute here). The board views are rendered by
datasets_synthetic.board_views with Mitsuba's direct-light integrator (why, and what it costs
the board's photometry, there); the scene's photos with the scene's path tracer.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import re
import shutil
import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation
from tqdm import tqdm

from datasets_synthetic.board import Checkerboard
from datasets_synthetic.board_views import BOARD_INTEGRATOR, FLASH_W_PER_SR, board_description, calibration_set
from datasets_synthetic.dng import DngMetadata, write_dng
from datasets_synthetic.jpeg import develop, hidden_response, write_jpeg
from datasets_synthetic.sensor import SensorModel, as_shot_neutral, auto_exposure, checked_vignetting, xyz_to_camera
from renderer.render import with_resolution
from renderer.rerender import FitRenderer
from renderer.scene import load_scene
from renderer.spectra import camera_sensitivities, light_spectrum
from renderer.tables import table_keys
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write, atomic_write_text
from workbench.core.version import __version__ as workbench_version
from workbench.core.version import versions

PRESETS = {
    "draft": {"resolution": (640, 480), "spp": 64, "views": 2, "calibration_views": 20, "calibration_spp": 16},
    "full": {"resolution": (978, 734), "spp": 512, "views": 3, "calibration_views": 15, "calibration_spp": 64},
    # a 24-megapixel photo for the report's page of a large photo (issue 27); noisy, few boards: not for accuracy
    "large": {"resolution": (6000, 4000), "spp": 2, "views": 1, "calibration_views": 4, "calibration_spp": 1},
}
BRACKET_EV = (-2, -1, 0, 1, 2)  # view0 re-exposed, 1 EV apart, RAW+JPEG: the response curve's bracket
HIGHLIGHT_EV = (-4, -6)  # darker frames of view0 for the CD's first orders (30-60x the walls' level: clipped at ev-2);
# taken after the board views, so the frames before them keep their noise draws
ALL_BRACKET_EV = tuple(sorted(BRACKET_EV + HIGHLIGHT_EV))
MARKER = "workbench-synthetic-dataset"
WORK_SUFFIX = ".synth-partial"  # the work folder beside DIR: .DIR.synth-partial/{request.json, renders/, dataset/}
WORK_FORMAT = "workbench-synthetic-dataset-work"
LEGACY_LAYOUT = re.compile(  # the files of a dataset written before run.json listed them
    r"photos/view\d+\.dng|brackets/ev[+-]\d+\.(dng|jpg)|calibration/board(\d+\.dng|\.json)|truth\.json|run\.json")
MAKE, MODEL, ISO = "Workbench", "Synthetic RGGB", 100


def hidden_camera(camera, rng: np.random.Generator):
    """The scene camera perturbed: rotation up to ~2 deg, translation ~2 cm, FOV ~2 deg,
    principal point ~1 % of the width, a mild distortion.
    """
    T = camera.world_to_camera.copy()
    dR = Rotation.from_rotvec(np.radians(rng.normal(0.0, 1.0, 3))).as_matrix()
    origin = -T[:3, :3].T @ T[:3, 3] + rng.normal(0.0, 0.01, 3)
    R = dR @ T[:3, :3]
    T[:3, :3], T[:3, 3] = R, -R @ origin
    fov = 2 * math.degrees(math.atan(0.5 * camera.width / camera.fx)) + rng.normal(0.0, 1.0)
    f = 0.5 * camera.width / math.tan(math.radians(fov) / 2)
    fy, cx, cy = f * (1 + rng.normal(0, 0.002)), camera.cx + rng.normal(0, 0.01 * camera.width), \
        camera.cy + rng.normal(0, 0.01 * camera.height)
    dist = ((float(rng.normal(-0.08, 0.03)), float(rng.normal(0.02, 0.01)), float(rng.normal(0, 5e-4)),
             float(rng.normal(0, 5e-4)), 0.0) if camera.model == "pinhole"
            else tuple(float(d + rng.normal(0.0, 0.005)) for d in camera.dist))  # other lenses: their own, a little off
    return dataclasses.replace(camera, world_to_camera=T, fx=f, fy=fy, cx=cx, cy=cy, dist=dist)


def orbit(camera, yaw_deg: float, pitch_deg: float):
    """The same camera moved around the point its optical axis meets the floor (y = 0), or
    the point 1 m ahead when it looks level: a second photograph of the same scene.
    """
    cam_to_world = np.linalg.inv(camera.world_to_camera)
    origin, axis = cam_to_world[:3, 3], cam_to_world[:3, 2]
    distance = -origin[1] / axis[1] if axis[1] < -0.05 else 1.0
    pivot = origin + distance * axis
    right = cam_to_world[:3, 0]
    yaw = Rotation.from_rotvec(np.radians(yaw_deg) * np.array([0.0, 1.0, 0.0]))
    turn = yaw * Rotation.from_rotvec(np.radians(pitch_deg) * right)
    moved = np.eye(4)
    moved[:3, :3] = turn.as_matrix() @ cam_to_world[:3, :3]
    moved[:3, 3] = pivot + turn.apply(origin - pivot)
    return dataclasses.replace(camera, world_to_camera=np.linalg.inv(moved))


@dataclasses.dataclass
class _Shot:
    """What truth.json says of one file."""

    exposure_time_s: float
    world_to_camera: np.ndarray


class _Writer:
    """Writes raw frames (DNG, and the camera's JPEG where asked) and collects their truth."""

    def __init__(self, out: Path, sensor: SensorModel, response, colour: dict) -> None:
        self.out, self.sensor, self.response, self.colour = out, sensor, response, colour
        self.shots: dict[str, _Shot] = {}

    def capture(self, folder: str, stem: str, rgb: np.ndarray, exposure_s: float, camera, rng, jpeg: bool = False) -> np.ndarray:
        if self.sensor.vignetting_power is not None:  # the lens's relative illumination (datasets_synthetic.sensor)
            rgb = rgb * self.sensor.relative_illumination(camera)
        raw = self.sensor.capture(rgb, exposure_s, rng)
        meta = DngMetadata(cfa_pattern=self.sensor.cfa_pattern, black_level=self.sensor.black_level,
                           white_level=self.sensor.white_level, exposure_time_s=exposure_s, iso=ISO, make=MAKE, model=MODEL,
                           as_shot_neutral=tuple(self.colour["as_shot_neutral"]),
                           color_matrix=tuple(self.colour["color_matrix"]))
        write_dng(self.out / folder / f"{stem}.dng", raw, meta)
        self.shots[f"{stem}.dng"] = _Shot(exposure_s, camera.world_to_camera)
        if jpeg:
            write_jpeg(self.out / folder / f"{stem}.jpg", develop(raw, self.sensor, self.response),
                       exposure_time_s=exposure_s, iso=ISO, make=MAKE, model=MODEL)
            self.shots[f"{stem}.jpg"] = _Shot(exposure_s, camera.world_to_camera)
        return raw


def synth(scene: str, out: str | Path, *, seed: int = 0, preset: str = "draft", force: bool = False,
          progress: bool = True, notify: Callable[[str], None] | None = None, render_seed: int | None = None,
          vignetting: tuple[float, float, float] | None = None) -> dict:
    """Write the dataset for ``scene`` into ``out``; returns the truth (also in truth.json).

    ``render_seed`` (default: ``seed``) seeds the renders' Monte Carlo alone: the same
    ``seed`` with another ``render_seed`` is the same hidden camera, poses, exposures and
    sensor noise streams over another realisation of the renders' noise, which is what a
    dataset's numbers spread over when another CPU renders it (benchmarks/bench_calibration.py).
    ``vignetting``: the lens's cos^p falloff, p per channel (SensorModel.vignetting_power).

    Everything is checked before anything is written. The dataset is made in a work folder
    beside ``out`` (``.NAME.synth-partial``) and moved into place when complete, so an
    interrupted run leaves ``out`` as it was; the work folder keeps the finished renders,
    and the same command resumes from them (same bytes as an uninterrupted run).
    ``force`` replaces a previous dataset, only if ``out`` holds nothing but the files its
    run.json lists (unchanged); anything else there is refused by name.
    """
    say = notify or (_say if progress else (lambda _message: None))
    spec, p, folder = _checked_request(scene, out, seed, preset)
    p = p if vignetting is None else p | {"vignetting_power": checked_vignetting(vignetting)}
    render_seed = seed if render_seed is None else _checked_seed(render_seed, "render_seed")
    work = folder.parent / f".{folder.name}{WORK_SUFFIX}"
    _restore_interrupted_swap(folder, work)
    _check_output(folder, force)
    renders = _RenderStore(work, _request_key(spec, seed, preset, p, render_seed))
    if renders.count:
        say(f"resuming: {renders.count} renders finished by an earlier run of this request are reused ({work})")
    staging = work / "dataset"
    try:
        check_free_space(folder, required_bytes(p, renders.count))  # here: a refusal removes an empty work folder
        truth = _generate(spec, scene, staging, renders, (seed, render_seed), preset, p, progress)
        _check_output(folder, force)  # again: the folder may have changed while we rendered
        _move_into_place(staging, folder, work)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        if renders.count == 0:  # nothing worth resuming: leave nothing behind
            shutil.rmtree(work, ignore_errors=True)
        raise
    shutil.rmtree(work)
    return truth


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


SPACE_MARGIN_BYTES = 16 * 2**20  # run.json, truth.json, board.json and the file system's own rounding


def required_bytes(settings: dict, renders_done: int = 0) -> int:
    """Disk space a synth run of ``settings`` (a preset) still needs, an upper bound: the work
    folder's renders (float32 RGB, one per photo and board view, less the ``renders_done``
    kept from an earlier run) and the dataset's files (16-bit raw DNGs of every photo, board
    view and bracket frame, and 8-bit JPEGs of the brackets, uncompressed sizes)."""
    width, height = settings["resolution"]
    renders = settings["views"] + settings["calibration_views"]
    scratch = max(0, renders - renders_done) * width * height * 3 * 4
    raws = (renders + len(ALL_BRACKET_EV)) * width * height * 2
    jpegs = len(ALL_BRACKET_EV) * width * height * 3
    return scratch + raws + jpegs + SPACE_MARGIN_BYTES


def check_free_space(folder: Path, needed: int) -> None:
    """Refuse to start when the file system that will hold ``folder`` has less than ``needed``
    bytes free: a run that fills the disk half-way fails after minutes of rendering."""
    existing = next(p for p in (folder, *folder.parents) if p.exists())
    free = shutil.disk_usage(existing).free
    if free < needed:
        raise UserInputError("not enough free disk space for this dataset", file=existing,
                             expected=f"{needed / 1e6:.0f} MB free (the renders' scratch and the dataset's files)",
                             got=f"{free / 1e6:.0f} MB free")


def _checked_request(scene: str, out: str | Path, seed: int, preset: str) -> tuple[Any, dict, Path]:
    """(scene spec, preset settings, absolute output path), or a UserInputError before anything is written."""
    if preset not in PRESETS:
        raise UserInputError("unknown preset", field="--preset", expected=f"one of {sorted(PRESETS)}", got=preset)
    _checked_seed(seed, "--seed")
    spec = load_scene(scene)
    if spec.camera is None:  # pragma: no cover - the scene format requires a camera
        raise UserInputError("the scene has no camera", field="camera")
    out = Path(os.path.abspath(out))
    if out.exists() and not out.is_dir():
        raise UserInputError("is a file, not a folder", field="--out", expected="a new folder or a dataset's folder",
                             got=str(out))
    return spec, PRESETS[preset], out


def _checked_seed(seed: int, field: str) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**32:
        raise UserInputError("must be an integer in 0..4294967295", field=field, got=seed)
    return int(seed)


def _request_key(spec, seed: int, preset: str, settings: dict, render_seed: int) -> str:
    """What a dataset is of: the scene's text and tables, seeds, preset, workbench version."""
    request = {"scene": spec.text, "tables": table_keys(spec), "seed": seed, "preset": preset,
               "render_seed": render_seed, "board_integrator": BOARD_INTEGRATOR,
               "settings": {k: list(v) if isinstance(v, tuple) else v for k, v in settings.items()},
               "version": workbench_version}
    return hashlib.sha256(json.dumps(request, sort_keys=True).encode()).hexdigest()


def _dataset_files(folder: Path) -> dict[str, dict]:
    """Every file under ``folder`` but run.json, by relative path: size and SHA-256."""
    files = {}
    for path in sorted(p for p in folder.rglob("*") if p.is_file() or p.is_symlink()):
        rel = path.relative_to(folder).as_posix()
        if rel != "run.json":
            files[rel] = {"bytes": path.stat().st_size, "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}
    return files


def _check_output(out: Path, force: bool) -> None:
    """Raise unless ``out`` is new, empty (empty folders count as empty), or, with ``force``,
    holds exactly a previous dataset's files as its run.json lists them.
    """
    if not out.exists():
        return
    present = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if not p.is_dir() or p.is_symlink())
    if not present:
        return
    listed = _listed_files(out) or _legacy_dataset(out, present)
    if listed is None:
        raise UserInputError(f"the output folder holds files that no dataset of this workbench listed "
                             f"({_names(present)}); it is never replaced, not even with --force", file=out,
                             expected="a new or empty folder")
    foreign = [rel for rel in present if rel != "run.json" and rel not in listed]
    changed = [rel for rel in present if rel in listed and not _unchanged(out / rel, listed[rel])]
    if foreign or changed:
        parts = ([f"files that are not the dataset's ({_names(foreign)})"] if foreign else []) + \
                ([f"dataset files changed since they were written ({_names(changed)})"] if changed else [])
        raise UserInputError(f"the output folder holds {' and '.join(parts)}; --force replaces only a dataset's own "
                             "files", file=out, expected="a new or empty folder, or one holding only a dataset")
    if not force:
        raise UserInputError("the output folder is not empty (it holds another dataset)", file=out,
                             expected="a new or empty folder, or --force to replace the dataset")


def _listed_files(out: Path) -> dict[str, dict | None] | None:
    """The files a dataset's run.json lists, or None if ``out`` has no run.json of a dataset
    that lists its files.
    """
    try:
        record = json.loads((out / "run.json").read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("format") != MARKER or not isinstance(record.get("files"), dict):
        return None
    return record["files"]


def _legacy_dataset(out: Path, present: list[str]) -> dict[str, None] | None:
    """A dataset written before run.json listed its files: recognised by its truth.json and
    by every file having a name of the layout (nothing to check their bytes against)."""
    try:
        ours = MARKER in (out / "truth.json").read_text()[:200]
    except (OSError, UnicodeDecodeError):
        return None
    if not ours or not all(LEGACY_LAYOUT.fullmatch(rel) for rel in present):
        return None
    return dict.fromkeys(present)


def _unchanged(path: Path, listed: dict | None) -> bool:
    if listed is None:  # a legacy dataset's file
        return not path.is_symlink()
    try:
        if path.is_symlink() or path.stat().st_size != listed.get("bytes"):
            return False
        return hashlib.sha256(path.read_bytes()).hexdigest() == listed.get("sha256")
    except OSError:
        return False


def _names(paths: list[str], shown: int = 8) -> str:
    return ", ".join(paths[:shown]) + (f" and {len(paths) - shown} more" if len(paths) > shown else "")


class _RenderStore:
    """The renders of one request, kept in the work folder until the dataset is in place, so
    a killed run resumes from them. A work folder of another request is ours to empty; a
    folder of that name we did not make is refused.
    """

    def __init__(self, work: Path, key: str) -> None:
        self.folder = work / "renders"
        self.reused = 0
        record = work / "request.json"
        if work.exists():
            try:
                recorded = json.loads(record.read_text())
            except (OSError, ValueError):
                recorded = None
            if not isinstance(recorded, dict) or recorded.get("format") != WORK_FORMAT:
                if any(work.iterdir()):
                    raise UserInputError("a folder this workbench did not make is in the way of the dataset's work "
                                         "folder", file=work, expected="that folder moved away")
            elif recorded.get("key") != key:
                shutil.rmtree(work)  # the renders of another request (seed, scene, preset)
        atomic_write_text(record, json.dumps({"format": WORK_FORMAT, "key": key}))  # first: it marks the folder ours
        self.folder.mkdir(parents=True, exist_ok=True)

    @property
    def count(self) -> int:
        return sum(1 for _ in self.folder.glob("*.npy")) if self.folder.is_dir() else 0

    def get(self, name: str, render: Callable[[], np.ndarray]) -> np.ndarray:
        """The stored render ``name``, or ``render()`` stored atomically."""
        path = self.folder / f"{name}.npy"
        try:
            stored = np.load(path)
            self.reused += 1
            return stored
        except (OSError, ValueError, EOFError):  # not rendered yet, or a damaged file: render again
            pass
        rgb = render()

        def write(tmp: Path) -> None:
            with open(tmp, "wb") as f:
                np.save(f, rgb)
                f.flush()
                os.fsync(f.fileno())
        atomic_write(path, write)
        return rgb


def _move_into_place(staging: Path, out: Path, work: Path) -> None:
    """Put the finished dataset at ``out``: one rename when ``out`` is new; otherwise the old
    dataset's entries move into the work folder and the new ones in (run.json last), with
    their names recorded so that an interruption in between is undone on the next run.
    """
    if not out.exists():
        os.rename(staging, out)
        return
    new = sorted(p.name for p in staging.iterdir() if p.name != "run.json") + ["run.json"]
    old_folder = work / "old"
    old_folder.mkdir()
    atomic_write_text(work / "swap.json", json.dumps({"new": new}), sync=True)
    for child in list(out.iterdir()):
        os.rename(child, old_folder / child.name)
    for name in new:
        os.rename(staging / name, out / name)


def _restore_interrupted_swap(out: Path, work: Path) -> None:
    """Undo a move into place that was interrupted: the old dataset goes back."""
    old_folder, record = work / "old", work / "swap.json"
    if not old_folder.is_dir() or not record.is_file():
        return
    for name in json.loads(record.read_text())["new"]:
        if (out / name).exists() and not (old_folder / name).exists():
            _remove(out / name)
    for child in list(old_folder.iterdir()):
        if (out / child.name).exists():
            _remove(out / child.name)
        os.rename(child, out / child.name)
    old_folder.rmdir()
    record.unlink()


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink()


def _generate(spec, scene: str, out: Path, renders: _RenderStore, seeds: tuple[int, int], preset: str, p: dict,
              progress: bool) -> dict:
    """Render and write the whole dataset into ``out`` (the staging folder); the truth.
    ``seeds``: the dataset's seed and the renders' (synth's ``render_seed``)."""
    started = time.perf_counter()
    seed, render_seed = seeds
    shutil.rmtree(out, ignore_errors=True)  # a half-written dataset of a killed run
    for sub in ("photos", "brackets", "calibration"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    rng_camera, rng_views, rng_noise, rng_board = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(4))
    spec = with_resolution(spec, p["resolution"])
    camera = hidden_camera(spec.camera.model, rng_camera)
    exposure_scale = float(np.exp(rng_camera.normal(0.0, 0.3)))
    light_scale = float(np.exp(rng_camera.normal(0.0, 0.3)))
    response = hidden_response(rng_camera)
    sensor = SensorModel(vignetting_power=p.get("vignetting_power"))
    writer = _Writer(out, sensor, response, colour_tags(spec))
    hidden = dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, model=camera))
    bar = tqdm(total=p["views"] + p["calibration_views"], desc="synth renders", unit="frame", disable=not progress)
    timings: dict[str, float] = {}

    tick = time.perf_counter()
    rgb, exposure_s = _photos(hidden, camera, p, light_scale, exposure_scale, render_seed, writer, rng_views, rng_noise, bar,
                              renders)
    timings["photos_s"] = time.perf_counter() - tick

    tick = time.perf_counter()
    for ev in BRACKET_EV:
        writer.capture("brackets", f"ev{ev:+d}", rgb, exposure_s * 2.0**ev, camera, rng_noise, jpeg=True)
    timings["brackets_s"] = time.perf_counter() - tick

    tick = time.perf_counter()
    board = Checkerboard()
    poses = calibration_set(hidden, camera, board, p, light_scale, partial(_frame_seed, render_seed), writer,
                            (rng_board, rng_noise), bar, renders)
    atomic_write_text(out / "calibration" / "board.json", json.dumps(board_description(board), indent=2) + "\n")
    timings["calibration_s"] = time.perf_counter() - tick
    for ev in HIGHLIGHT_EV:
        writer.capture("brackets", f"ev{ev:+d}", rgb, exposure_s * 2.0**ev, camera, rng_noise, jpeg=True)
    bar.close()

    truth = _truth(spec, seed, preset, camera, writer, response, light_scale, exposure_scale, board, poses)
    truth["render_seed"] = render_seed
    atomic_write_text(out / "truth.json", json.dumps(truth, indent=2))
    timings["total_s"] = time.perf_counter() - started
    _write_run_record(out, scene, seed, preset, p | {"render_seed": render_seed, "board_integrator": BOARD_INTEGRATOR},
                      timings, renders.reused)
    return truth


def _photos(hidden, camera, p: dict, light_scale: float, exposure_scale: float, render_seed: int, writer: _Writer,
            rng_views, rng_noise, bar, renders: _RenderStore) -> tuple[np.ndarray, float]:
    """The views of the scene (photos/): view0 from the hidden camera, the others orbiting
    it; view0's render and exposure time, which the brackets re-expose."""
    fit = FitRenderer(hidden, resolution=p["resolution"], spp=p["spp"])
    fit.set(light_power_scale=light_scale)
    view0 = None
    for k in range(p["views"]):
        view_camera = camera if k == 0 else orbit(camera, rng_views.choice([-1, 1]) * rng_views.uniform(6, 12),
                                                   rng_views.uniform(-3, 3))
        fit.set(camera=view_camera)
        rgb = renders.get(f"view{k}", partial(fit.render, seed=_frame_seed(render_seed, k)))
        exposure_s = auto_exposure(rgb, writer.sensor) * exposure_scale
        writer.capture("photos", f"view{k}", rgb, exposure_s, view_camera, rng_noise)
        if k == 0:
            view0 = (rgb, exposure_s)
        bar.update()
    assert view0 is not None, "the presets have at least one view"
    return view0


def _truth(spec, seed: int, preset: str, camera, writer: _Writer, response, light_scale: float, exposure_scale: float,
           board: Checkerboard, poses: dict[str, np.ndarray]) -> dict:
    """truth.json's content (module docstring)."""
    sensor = writer.sensor
    return {
        "format": MARKER, "seed": seed, "preset": preset, "scene": spec.name,
        "camera": {"width": camera.width, "height": camera.height, "fx": camera.fx, "fy": camera.fy,
                   "cx": camera.cx, "cy": camera.cy, "dist": list(camera.dist), "model": camera.model, "xi": camera.xi,
                   "world_to_camera": {name: shot.world_to_camera.tolist() for name, shot in writer.shots.items()}},
        "exposure_time_s": {name: shot.exposure_time_s for name, shot in writer.shots.items()},
        "response": response.to_json() | {"applies_to": "brackets/*.jpg (the DNGs are linear)"},
        "light_power_scale": light_scale,
        "exposure_scale": exposure_scale,
        "board": board.to_json() | {"board_to_world": {name: pose.tolist() for name, pose in poses.items()},
                                    "flash": {"at": "the camera's centre", "intensity_w_per_sr": FLASH_W_PER_SR,
                                              "spectrum": spec.light.spectrum}},
        "brackets": {"of": "view0.dng", "ev": list(ALL_BRACKET_EV)},
        "sensor": dataclasses.asdict(sensor) | {"white_level": sensor.white_level} | writer.colour,
    }


def colour_tags(spec) -> dict:
    """The DNG colour tags of every file (datasets_synthetic.sensor): ``as_shot_neutral``, the
    scene camera's RGB of a white diffuse surface under the scene light's spectrum (the
    ceiling light's and the flash's, which share it), G = 1; ``color_matrix``, XYZ to camera
    RGB under D65 (ColorMatrix1), row-major. From the camera's spectral sensitivities, the
    renderer's own data (renderer.spectra)."""
    curves = camera_sensitivities(spec.camera.sensitivities)
    wl = np.unique(np.concatenate([w for w, _ in curves]))
    sensitivities = np.stack([np.interp(wl, w, s, left=0.0, right=0.0) for w, s in curves])
    light_wl, light = light_spectrum(spec.light.spectrum)
    light = np.interp(wl, light_wl, light, left=0.0, right=0.0)
    return {"as_shot_neutral": list(as_shot_neutral(wl, sensitivities, light)),
            "color_matrix": list(xyz_to_camera(wl, sensitivities)), "color_matrix_illuminant": "D65"}


def _frame_seed(seed: int, frame: int) -> int:
    """A frame's Mitsuba seed, inside its unsigned 32 bits (``--seed`` reaches 2**32 - 1)."""
    return (seed * 1000 + frame) % 2**32


def _write_run_record(out: Path, scene: str, seed: int, preset: str, settings: dict, timings: dict,
                      resumed_renders: int) -> None:
    """run.json: settings, timings, versions, and every file the run wrote (size, SHA-256),
    which is what ``--force`` may replace.
    """
    record = {"format": MARKER, "command": "workbench synth", "scene": scene, "seed": seed, "preset": preset,
              "settings": settings, "timings": timings, "resumed_renders": resumed_renders,
              "versions": versions("mitsuba", "drjit", "numpy"),
              "files": _dataset_files(out)}
    atomic_write_text(out / "run.json", json.dumps(record, indent=2, default=list))

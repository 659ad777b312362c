"""``workbench study calibrate DATASET --scene SCENE --out DIR``: what accuracy costs in time
for the pose and field-of-view refinement (calibration.pose.calibrate) on a synthetic dataset.

The study reads the dataset's truth.json (the calibration itself never does): every
setting's fitted cameras and photometric scales are compared with the truth. Settings are
varied one at a time around ``base`` (calibration.pose.calibrate.PoseSettings, the defaults of
``calibrate DATASET``):

* ``fine``: the fine stage's rounds per window and its shrinking search windows
  (PoseSettings.fine_rounds, fine_windows_px);
* ``scale``: the fit resolution, the photo downscaled by pixel-area averaging (cv2.INTER_AREA)
  and the camera's intrinsics scaled with it (f s, (c + 1/2) s - 1/2 in OpenCV's pixel
  convention, distortion unchanged: it acts on normalised coordinates); the render check
  renders at that resolution; the fitted camera is scaled back before it is compared;
* ``render_spp``: the samples per pixel of the render check (exposure x light power and
  the edge finder's bias, PoseSettings.render_spp), each one fixed render (render_pass_spp
  the same: without it render_spp is only the cap of the passes that stop at their noise).

Each setting fits every photo of the dataset (photos/), with the intrinsics from the board
views held fixed as ``calibrate DATASET`` does, or, with ``free_intrinsics``, fitted from
each photo (the path without board views, where the field of view is refined too). Its
seconds are the pose fits' wall time (the renderer's construction, once per resolution
and spp, is recorded apart as ``setup_s``). Errors, the worst photo's: rotation (deg),
camera centre (mm), horizontal or vertical field of view (deg), principal point (% of
the image side), exposure x light power (% of the sensor model's value). With the
intrinsics held, FOV and principal point are the boards' and do not change with the
settings. The response curve's own accuracy-for-time, the parametric fit's knot count
(calibration.response.calibrate.parametric_knot_study), is measured on the dataset's JPEG bracket.

Measured on the draft dataset of seed 0 (both photos, default grid; seconds taken on the
shared 2-core machine under a load of about 10, so several times what an idle one takes):
at full resolution the default settings give 0.065 deg and 0.35 mm, exposure x light
within 0.10 %; half resolution 0.075 deg, 0.48 mm in a third of the time; a quarter
0.16 deg, 1.95 mm (over issue 14's 1 mm) in a seventh. The render check's spp moves the
camera centre by a tenth of a millimetre (4 spp: 0.28 mm, 64 spp: 0.23 mm) at 0.5 to 3.5
times the cost, and one fine round per window is as good as four (the fine stage
converges in one). The response: 3 knots 0.10 % RMS, 2 knots 1.0 %, 8 knots 0.8 %
(over-fitted noise), each about 0.3 s.

Outputs in DIR, each written atomically: study_calibrate.json (settings, versions,
timings, every row), calibrate_settings.csv (one row per setting), calibrate_photos.csv
(one per setting and photo), response_knots.csv, and study_calibrate.png/.svg (error
against seconds), in the layout of ``study rcwa`` and ``study render`` for the HTML report.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from tqdm import tqdm

from calibration.dataset import IMAGE_SUFFIXES, dataset_board, dataset_files, held_intrinsics, intrinsics_from_boards
from calibration.pose.edge_fit import FREE_RADIAL_TERMS, PoseSettings, Unknowns
from calibration.pose.inputs import fit_renderer, start_camera
from calibration.pose.outputs import versions
from calibration.pose.photo import read_photo
from calibration.pose.scene_model import scene_model
from calibration.pose.stages import check_photo, fit_photo
from calibration.response.bracket import read_bracket
from calibration.response.methods import parametric_knot_study
from renderer.camera import CameraModel
from renderer.scene import load_scene
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_csv, atomic_write_text
from workbench.core.plots import new_figure, save_figure

STUDY_FORMAT = "workbench-study-calibrate"
SYNTHETIC_FORMAT = "workbench-synthetic-dataset"  # truth.json's marker (datasets_synthetic.synth.MARKER)
ERRORS = ("rotation_deg", "centre_mm", "fov_deg", "principal_point_pct", "exposure_pct")
FACTORS = ("fine", "scale", "render_spp")


@dataclass(frozen=True)
class CalibrateStudyConfig:
    """The settings varied (one at a time around ``base``) and the knot counts of the response study."""

    fine: tuple[tuple[int, tuple[float, ...]], ...] = ((1, (6.0, 3.0)), (2, (6.0, 4.0, 3.0)), (4, (6.0, 4.0, 3.0, 2.5)))
    scales: tuple[float, ...] = (1.0, 0.5, 0.25)
    render_spp: tuple[int, ...] = (4, 16, 64)
    knots: tuple[int, ...] = (2, 3, 4, 6, 8)
    free_intrinsics: bool = False
    photos: tuple[str, ...] = ()   # file names in photos/ to fit; empty: every photo
    base: PoseSettings = field(default_factory=PoseSettings)

    def settings(self) -> list[tuple[str, PoseSettings, float]]:
        """(factor, pose settings, scale) for every setting, one factor varied at a time;
        the base setting is listed under each factor (measured once)."""
        rows: list[tuple[str, PoseSettings, float]] = []
        for rounds, windows in self.fine:
            rows.append(("fine", dataclasses.replace(self.base, fine_rounds=rounds, fine_windows_px=tuple(windows)), 1.0))
        rows += [("scale", self.base, s) for s in self.scales]
        rows += [("render_spp", dataclasses.replace(self.base, render_spp=n, render_pass_spp=n), 1.0)  # one fixed render
                 for n in self.render_spp]
        return rows

    def to_json(self) -> dict:
        return {"fine": [{"fine_rounds": r, "fine_windows_px": list(w)} for r, w in self.fine], "scales": list(self.scales),
                "render_spp": list(self.render_spp), "knots": list(self.knots), "free_intrinsics": self.free_intrinsics,
                "photos": list(self.photos), "base": self.base.to_json()}


def check_config(cfg: CalibrateStudyConfig, width: int, height: int) -> None:
    """Every value usable before anything runs (UserInputError naming the setting)."""
    for rounds, windows in cfg.fine:
        if not isinstance(rounds, int) or rounds < 1 or not windows or not all(w > 0 for w in windows):
            raise UserInputError("fine rounds must be >= 1 with at least one positive window", field="fine",
                                 got=(rounds, windows))
    for s in cfg.scales:
        if not 0 < s <= 1 or abs(width * s - round(width * s)) > 1e-9 or abs(height * s - round(height * s)) > 1e-9:
            raise UserInputError("a fit scale must be in (0, 1] and give whole pixels", field="scales",
                                 expected=f"e.g. 1, 0.5, 0.25 of {width} x {height}", got=s)
    if not all(isinstance(n, int) and n >= 1 for n in cfg.render_spp):
        raise UserInputError("samples per pixel must be positive integers", field="render_spp", got=cfg.render_spp)
    if not all(isinstance(k, int) and k >= 2 for k in cfg.knots):
        raise UserInputError("knot counts must be integers >= 2", field="knots", got=cfg.knots)


# --------------------------------------------------------------------------------- truth and errors


def read_truth(dataset: Path, photos: list[Path]) -> dict:
    """The dataset's truth.json (a synthetic dataset's), checked to hold what the study compares."""
    path = dataset / "truth.json"
    if not path.is_file():
        raise UserInputError("the study compares with the truth, and this dataset has none", file=path,
                             expected="a synthetic dataset written by `workbench synth` (with truth.json)")
    try:
        truth = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise UserInputError(f"cannot be read as JSON ({exc})", file=path, expected="truth.json of `workbench synth`") from None
    if not isinstance(truth, dict) or truth.get("format") != SYNTHETIC_FORMAT:
        raise UserInputError("is not the truth of a synthetic dataset", file=path, field="format",
                             expected=repr(SYNTHETIC_FORMAT), got=truth.get("format") if isinstance(truth, dict) else None)
    for key in ("camera", "exposure_time_s", "sensor", "light_power_scale"):
        if key not in truth:
            raise UserInputError("is missing", file=path, field=key, expected="truth.json of `workbench synth`")
    missing = [p.name for p in photos if p.name not in truth["camera"].get("world_to_camera", {})]
    if missing:
        raise UserInputError("has no pose for these photos", file=path, field="camera.world_to_camera",
                             expected="one per file in photos/", got=missing)
    return truth


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle of the rotation between two world-to-camera matrices."""
    return math.degrees(math.acos(float(np.clip((np.trace(a[:3, :3] @ b[:3, :3].T) - 1) / 2, -1.0, 1.0))))


def centre_error_mm(a: np.ndarray, b: np.ndarray) -> float:
    return 1e3 * float(np.linalg.norm(-a[:3, :3].T @ a[:3, 3] + b[:3, :3].T @ b[:3, 3]))


def fov_deg(size: float, focal: float) -> float:
    """The full field of view (degrees) of ``size`` pixels at focal length ``focal`` pixels."""
    return 2 * math.degrees(math.atan(size / (2 * focal)))


def expected_exposure_scale(truth: dict, photo: str) -> float:
    """A synthetic photo's normalised raw value per unit of the scene file's render: light
    power scale x exposure time x electrons per unit x gain / (white - black)
    (datasets_synthetic.sensor's photon-transfer model)."""
    sensor = truth["sensor"]
    return (truth["light_power_scale"] * truth["exposure_time_s"][photo] * sensor["electrons_per_unit"] * sensor["gain"]
            / (sensor["white_level"] - sensor["black_level"]))


def photo_errors(camera, exposure_scale: float | None, truth: dict, photo: str) -> dict:
    """One fitted photo against the truth (units in the names)."""
    t = truth["camera"]
    fitted, true = camera.world_to_camera, np.asarray(t["world_to_camera"][photo], float)
    exposure = (100 * abs(exposure_scale / expected_exposure_scale(truth, photo) - 1)
                if exposure_scale is not None else float("nan"))
    return {"rotation_deg": rotation_error_deg(fitted, true), "centre_mm": centre_error_mm(fitted, true),
            "fov_deg": max(abs(fov_deg(camera.width, camera.fx) - fov_deg(t["width"], t["fx"])),
                           abs(fov_deg(camera.height, camera.fy) - fov_deg(t["height"], t["fy"]))),
            "principal_point_pct": 100 * max(abs(camera.cx - t["cx"]) / t["width"], abs(camera.cy - t["cy"]) / t["height"]),
            "exposure_pct": exposure}


# ---------------------------------------------------------------------------------- fit resolution


def scaled_camera(camera, scale: float):
    """``camera`` seen at ``scale`` of its resolution: f s, (c + 1/2) s - 1/2 (OpenCV's pixel
    centres at integers), same pose and distortion. ``scale`` < 1 downscales; 1 / scale undoes it."""
    return dataclasses.replace(camera, width=int(round(camera.width * scale)), height=int(round(camera.height * scale)),
                               fx=camera.fx * scale, fy=camera.fy * scale, cx=(camera.cx + 0.5) * scale - 0.5,
                               cy=(camera.cy + 0.5) * scale - 0.5)


def scaled_photo(photo, scale: float):
    """calibration.pose.photo.Photo downscaled by pixel-area averaging; a pixel is saturated where
    any pixel it covers was; no colour filter array any more (the render check then
    compares without mosaicking)."""
    if scale == 1.0:
        return photo
    size = (int(round(photo.width * scale)), int(round(photo.height * scale)))
    rgb = cv2.resize(photo.rgb, size, interpolation=cv2.INTER_AREA)
    saturated = cv2.resize(photo.saturated.astype(np.float32), size, interpolation=cv2.INTER_AREA) > 0
    return dataclasses.replace(photo, rgb=np.ascontiguousarray(rgb, np.float32), saturated=saturated, cfa=None)


def _scaled_intrinsics(known: dict | None, scale: float) -> tuple[dict | None, dict | None]:
    """Intrinsics held fixed, and their standard deviations, at ``scale``."""
    if known is None:
        return None, None
    template = CameraModel(width=known["width"], height=known["height"], fx=known["fx"], fy=known["fy"], cx=known["cx"],
                           cy=known["cy"], dist=tuple(known["dist"]), world_to_camera=np.eye(4))
    c = scaled_camera(template, scale)
    scaled = dict(known, width=c.width, height=c.height, fx=c.fx, fy=c.fy, cx=c.cx, cy=c.cy)
    std = known.get("std")
    if std is not None:
        std = dict(std) | {k: std[k] * scale for k in ("fx", "fy", "cx", "cy") if k in std}
    return scaled, std


# ----------------------------------------------------------------------------------------- the study


@dataclass
class _Inputs:
    spec: Any   # renderer.scene.SceneSpec
    photos: list
    known: dict | None
    truth: dict
    bracket: list[Path]
    intrinsics_s: float


class _Renderers:
    """One renderer.rerender.FitRenderer per (resolution, spp), built on first use; the seconds it took."""

    def __init__(self, spec) -> None:
        self.spec = spec
        self.built: dict[tuple[int, int, int], Any] = {}
        self.seconds: dict[tuple[int, int, int], float] = {}

    def get(self, start, spp: int):
        key = (start.width, start.height, spp)
        if key not in self.built:
            tick = time.perf_counter()
            renderer = fit_renderer(self.spec, start, spp)
            renderer.render(seed=0)  # the first render compiles its kernels: setup, not the fit's time
            self.built[key] = renderer
            self.seconds[key] = time.perf_counter() - tick
        return self.built[key]


def _prepare(dataset: Path, scene: str | Path, cfg: CalibrateStudyConfig) -> _Inputs:
    """Everything checked and read before the first fit: files, truth, photos, the boards' intrinsics."""
    spec = load_scene(scene)
    files = dataset_files(dataset)
    chosen = [p for p in files["photos"] if not cfg.photos or p.name in cfg.photos]
    unknown = sorted(set(cfg.photos) - {p.name for p in files["photos"]})
    if unknown:
        raise UserInputError("no such photos in the dataset", file=dataset / "photos", field="photos", got=unknown)
    truth = read_truth(dataset, chosen)
    photos = [read_photo(p) for p in chosen]
    for photo in photos:
        check_photo(photo)
        check_config(cfg, photo.width, photo.height)
    tick = time.perf_counter()
    known = None
    if not cfg.free_intrinsics:
        board = dataset_board(files, dataset)
        record = intrinsics_from_boards(files["boards"], board, progress=False)
        if record is not None:
            known = held_intrinsics(record)
    bracket = [p for p in files["brackets"] if p.suffix.lower() in IMAGE_SUFFIXES]
    return _Inputs(spec, photos, known, truth, bracket, time.perf_counter() - tick)


def _fit_setting(inputs: _Inputs, settings: PoseSettings, scale: float, renderers: _Renderers, bar) -> list[dict]:
    """Every photo fitted with ``settings`` at ``scale``: errors and seconds per photo."""
    model = scene_model(inputs.spec)
    known, known_std = _scaled_intrinsics(inputs.known, scale)
    unknowns = Unknowns(intrinsics=known is None, radial=FREE_RADIAL_TERMS if known is None else 0)
    rows = []
    for photo in inputs.photos:
        small = scaled_photo(photo, scale)
        start = start_camera(inputs.spec, small, known)
        renderer = renderers.get(start, settings.render_spp) if settings.render_check else None
        tick = time.perf_counter()
        result = fit_photo(small, model, start, unknowns, settings, renderer, None, known_std)
        seconds = time.perf_counter() - tick
        camera = scaled_camera(result.camera, 1.0 / scale)
        name = Path(photo.path).name
        rows.append({"photo": name, "seconds": seconds, **photo_errors(camera, result.exposure_scale, inputs.truth, name),
                     "edge_points": int(result.residuals.get("points", 0)),
                     "edge_residual_px": float(result.residuals.get("robust_sigma_px", float("nan"))) / scale})
        bar.update()
    return rows


def _knot_study(inputs: _Inputs, cfg: CalibrateStudyConfig) -> list[dict]:
    if len(inputs.bracket) < 2 or "response" not in inputs.truth:
        return []
    rows = parametric_knot_study(read_bracket(inputs.bracket), inputs.truth["response"]["points"], cfg.knots)
    return [{"knots": r["knots"], "response_rms_pct": 100 * r["rms"], "seconds": r["seconds"]} for r in rows]


def run_calibrate_study(dataset: str | Path, scene: str | Path, out: str | Path,
                        cfg: CalibrateStudyConfig | None = None, *, progress: bool = True) -> dict:
    """The study (module docstring); returns study_calibrate.json's content."""
    started = time.perf_counter()
    cfg = cfg or CalibrateStudyConfig()
    dataset, out = Path(dataset), Path(out)
    if out.exists() and not out.is_dir():
        raise UserInputError("is a file, not a folder", field="--out", expected="a folder for the study", got=str(out))
    inputs = _prepare(dataset, scene, cfg)
    plan = cfg.settings()
    bar = tqdm(total=len(plan) * len(inputs.photos) + 1, desc="study calibrate", unit="fit", disable=not progress)
    renderers = _Renderers(inputs.spec)
    measured: dict[tuple, list[dict]] = {}
    rows, per_photo = [], []
    for factor, settings, scale in plan:
        key = (settings, scale)
        if key not in measured:  # the base setting appears under every factor: fitted once
            measured[key] = _fit_setting(inputs, settings, scale, renderers, bar)
        else:
            bar.update(len(inputs.photos))
        photos = measured[key]
        row = {"factor": factor, "fine_rounds": settings.fine_rounds,
               "fine_windows_px": " ".join(f"{w:g}" for w in settings.fine_windows_px), "scale": scale,
               "render_spp": settings.render_spp, "seconds": float(sum(p["seconds"] for p in photos)),
               **{k: float(max(p[k] for p in photos)) for k in ERRORS}}
        rows.append(row)
        per_photo += [{"factor": factor, "fine_rounds": row["fine_rounds"], "fine_windows_px": row["fine_windows_px"],
                       "scale": scale, "render_spp": row["render_spp"]} | p for p in photos]
    knots = _knot_study(inputs, cfg)
    bar.update()
    bar.close()
    data = {"format": STUDY_FORMAT, "command": "workbench study calibrate", "dataset": str(dataset), "scene": str(scene),
            "intrinsics": "fitted from each photo" if inputs.known is None else inputs.known["source"],
            "photos": [Path(p.path).name for p in inputs.photos], "config": cfg.to_json(),
            "errors": {"rotation_deg": "deg", "centre_mm": "mm", "fov_deg": "deg (horizontal or vertical, the larger)",
                       "principal_point_pct": "% of the image width or height, the larger",
                       "exposure_pct": "% of exposure x light power", "worst": "the worst photo's"},
            "error_vs_time": rows, "per_photo": per_photo, "response_knots": knots,
            "versions": versions(),
            "timings": {"intrinsics_s": inputs.intrinsics_s,
                        "renderer_setup_s": {f"{w}x{h}@{spp}spp": s for (w, h, spp), s in renderers.seconds.items()},
                        "fits_s": float(sum(p["seconds"] for ps in measured.values() for p in ps)),
                        "total_s": time.perf_counter() - started}}
    _write(out, data)
    return data


def _write(out: Path, data: dict) -> None:
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_csv(out / "calibrate_settings.csv", data["error_vs_time"])
    atomic_write_csv(out / "calibrate_photos.csv", data["per_photo"])
    if data["response_knots"]:
        atomic_write_csv(out / "response_knots.csv", data["response_knots"])
    _plot(data, out)
    atomic_write_text(out / "study_calibrate.json", json.dumps(data, indent=2) + "\n")


def _plot(data: dict, out: Path) -> None:
    fig, axes = new_figure(3, size=(16, 4.4))
    style = {"fine": ("o", "C0"), "scale": ("s", "C1"), "render_spp": ("^", "C2")}
    for factor in FACTORS:
        rows = sorted((r for r in data["error_vs_time"] if r["factor"] == factor), key=lambda r: r["seconds"])
        seconds = [r["seconds"] for r in rows]
        mark, colour = style[factor]
        axes[0].loglog(seconds, [max(r["rotation_deg"], 1e-6) for r in rows], mark + "-", color=colour,
                       label=f"rotation (deg), {factor}")
        axes[0].loglog(seconds, [max(r["centre_mm"] / 10, 1e-6) for r in rows], mark + "--", color=colour, mfc="none",
                       label=f"centre (mm / 10), {factor}")
        axes[1].loglog(seconds, [max(r["exposure_pct"], 1e-6) for r in rows], mark + "-", color=colour, label=factor)
    axes[0].set(xlabel="pose fits, wall time (s)", ylabel="worst photo's error", title="pose against time (one factor varied)")
    axes[1].set(xlabel="pose fits, wall time (s)", ylabel="exposure x light power error (%)", title="photometry against time")
    knots = data["response_knots"]
    if knots:
        axes[2].semilogy([k["knots"] for k in knots], [k["response_rms_pct"] for k in knots], "o-", label="parametric fit")
        for k in knots:
            axes[2].annotate(f"{k['seconds']:.2f} s", (k["knots"], k["response_rms_pct"]), fontsize=8)
    axes[2].set(xlabel="knots", ylabel="response RMS over values 0.05-0.95 (%)", title="response curve: knots (fit time)")
    save_figure(fig, axes, out, "study_calibrate")

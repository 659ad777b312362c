"""``workbench calibrate DATASET --scene SCENE --out DIR``: every calibration step on a folder.

DATASET is the layout ``workbench synth`` writes, which a folder of real photographs can
follow as well::

    DATASET/photos/*        photos of the scene (raw: DNG, NEF, CR2, ...; or JPEG/PNG/TIFF)
    DATASET/brackets/*      optional: an exposure bracket (raw files and/or JPEG, PNG, TIFF)
    DATASET/calibration/*   optional: board views, and board.json describing the board
                            (calibration.board.board_file; --board COLSxROWS, --square-mm override it)

Steps, in order: the intrinsics from calibration/ (calibration.intrinsics.calibrate, Zhang's method),
the response from brackets/ (calibration.response.calibrate: the curve from the non-raw files, the
linearity check from the raw ones), then the pose of every photo with the intrinsics held
fixed (calibration.pose.calibrate), and the lens's vignetting from the photos' walls against renders
(calibration.intrinsics.vignetting_stage). Without board views the first photo's fit frees the focal
length, principal point and k1, k2, and the others hold them. Nothing but these three
folders is read: a dataset's truth.json never is.

DIR gets, each written atomically once everything has succeeded:

* ``calibration.json``: ``camera`` (width, height, fx, fy, cx, cy, dist, and
  ``world_to_camera`` by photo file name, 4 x 4, OpenCV axes, metres), ``std`` for each
  estimate, ``exposure_scale`` by photo (photo / render of the scene file, 1 = the white
  level; exposure x light power, which one photo cannot tell apart, so
  ``light_power_scale`` is held at 1), ``exposure_scale_per_second`` (divided by each
  photo's EXIF exposure time: what is left is the light and the sensor's gain, the same
  for every photo of one scene), ``response`` (``points``: pairs of normalised irradiance
  and value), residuals, ``cd_fringes`` by photo (calibration.pose.fringe_rotation: the CD-fringe
  photometric residual before and after, the rotation the fringes suggest, whether it
  was taken and why), ``vignetting`` (calibration.intrinsics.vignetting_stage: the lens's falloff
  per channel fitted on the walls against renders, its corners with std, whether it is
  applied and why; where it is, ``exposure_scale`` is the exposure on the lens's axis),
  settings, versions and timings;
* ``intrinsics.json`` (when board views were used) and ``response.json`` (when a
  bracket was), as their own commands write them;
* ``fitted_scene.toml``: the scene with the first photo's fitted camera and exposure, and
  ``scenes/NAME.toml`` the same for every photo (``workbench render`` loads them).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm import tqdm

from calibration.board.board_file import BoardSpec, resolve_board
from calibration.calibration_file import calibration_record, write_calibration
from calibration.intrinsics.calibrate import calibrate_board_views
from calibration.intrinsics.projection_uncertainty import map_over
from calibration.intrinsics.vignetting_stage import vignetting_stage
from calibration.pose.edge_fit import FREE_RADIAL_TERMS, PoseSettings, Unknowns
from calibration.pose.fringe_rotation import cd_mask
from calibration.pose.inputs import fit_renderer, start_camera
from calibration.pose.photo import RAW_SUFFIXES, read_photo
from calibration.pose.scene_model import scene_model
from calibration.pose.stages import PoseResult, check_photo, fit_photo
from calibration.response.calibrate import calibrate_response
from renderer.camera import CameraModel
from renderer.scene import load_scene
from workbench.core.errors import UserInputError
from workbench.core.timing import timed

IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png", ".tif", ".tiff"}


def _files(folder: Path) -> list[Path]:
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in RAW_SUFFIXES | IMAGE_SUFFIXES)


def dataset_files(dataset: str | Path) -> dict[str, list[Path]]:
    """The photos, bracket files and board views of a dataset folder (checked: photos exist)."""
    root = Path(dataset)
    if root.is_file():  # one photo and nothing else: say what a dataset holds and what each stage needs
        raise UserInputError("is a file, not a dataset folder", file=root,
                             expected=f"a folder DATASET with photos/{root.name}; " + "; ".join(stage_needs({"photos": [root]})))
    if not root.is_dir():
        raise UserInputError("no such dataset folder", file=root,
                             expected="a folder with photos/ (and optionally brackets/ and calibration/)")
    photos = _files(root / "photos")
    if not photos:
        raise UserInputError("the dataset has no photos", file=root / "photos",
                             expected="raw files (DNG, NEF, CR2, ...) or JPEG/PNG/TIFF images in photos/")
    names = [p.name for p in photos]
    if len(set(names)) != len(names):
        raise UserInputError("photo file names must be unique", file=root / "photos")
    return {"photos": photos, "brackets": _files(root / "brackets"), "boards": _files(root / "calibration")}


def stage_needs(files: dict[str, list[Path]]) -> list[str]:
    """What each calibration stage needs and what it does without it, for a dataset's files (or none):
    the lines a person with one photo reads first (issue 45, item 7)."""
    photos = files.get("photos", [])
    raw = bool(photos) and all(p.suffix.lower() in RAW_SUFFIXES for p in photos)
    boards, brackets = files.get("boards", []), files.get("brackets", [])
    lines = [
        f"intrinsics: {len(boards)} board views in calibration/ (with board.json, or --board and --square-mm)" if boards
        else "intrinsics: no board views in calibration/, so the first photo's pose fit frees the focal length, "
             "principal point and k1, k2 (put 10 or more board views in calibration/ for a lens you can trust)",
        ("response: raw photos are linear; a bracket in brackets/ only checks it" if raw else
         f"response: from the {len(brackets)} bracket frames in brackets/") if brackets or raw
        else "response: none (JPEG photos need an exposure bracket in brackets/, or shoot raw: a raw file is linear)",
        "pose, vignetting, scene fit and report: run on the photos in photos/ with what the stages above give",
    ]
    return lines


def dataset_board(files: dict[str, list[Path]], dataset: str | Path, board: tuple[int, int] | None = None,
                  square_mm: float | None = None) -> BoardSpec | None:
    """The board of the dataset's calibration views (calibration.board.board_file.resolve_board:
    calibration/board.json, overridden by ``board``/``square_mm``), or None without views."""
    if not files["boards"]:
        return None
    return resolve_board(Path(dataset) / "calibration", board, square_mm)


def intrinsics_from_boards(boards: list[Path], board: BoardSpec | None, progress: bool,
                           model: str = "auto") -> dict | None:
    """intrinsics.json's content from the board views (calibration.intrinsics.calibrate; ``model``: a lens
    model of renderer.lens, or ``auto``), or None without views."""
    if not boards or board is None:
        return None
    calibration = calibrate_board_views(boards, board.size, board.square_mm / 1000.0, charuco=board.charuco(),
                                        progress=progress, model=model)
    record = calibration.to_json()
    return record | {"source": f"{boards[0].parent} ({len(boards)} views)", "timings": calibration.timings,
                     "settings": {"board": board.to_json()}}


def response_from_bracket(brackets: list[Path], progress: bool) -> dict | None:
    """The response curve from the bracket's non-raw files, the linearity of its raw ones."""
    if not brackets:
        return None
    images = [p for p in brackets if p.suffix.lower() in IMAGE_SUFFIXES]
    raws = [p for p in brackets if p.suffix.lower() in RAW_SUFFIXES]
    result: dict = {}
    if images:
        result = calibrate_response(images, progress=progress)
    if raws:
        linearity = calibrate_response(raws)
        result = result or linearity
        result["raw_linearity"] = linearity.get("linearity", linearity)
    return result


def calibrate_dataset(dataset: str | Path, scene: str | Path, out: str | Path, *, board: tuple[int, int] | None = None,
                      square_mm: float | None = None, settings: PoseSettings | None = None,
                      progress: bool = True, model: str = "auto", executor=None) -> dict:
    """Run every step on ``dataset`` and write DIR's files (module docstring); returns calibration.json's content.

    ``board`` (inner corners or ChArUco squares, cols x rows) and ``square_mm`` override
    the dataset's calibration/board.json; without that file both are needed when there are
    board views (a UserInputError naming the file and the flags, before anything runs).
    ``model``: the board views' lens model (a model of renderer.lens, or ``auto``:
    calibration.intrinsics.lens_choice picks the simplest that held-out views do not reject).
    ``executor`` (workbench.core.executor.DaskExecutor): the intrinsics and the response run as two
    tasks and each photo's pose as its own (fit_photos_on); the vignetting, over all photos, here."""
    started = time.perf_counter()
    settings = settings or PoseSettings()
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserInputError("is a file, not a folder", field="--out", expected="a folder for the results", got=str(out))
    spec = load_scene(scene)
    files = dataset_files(dataset)
    board_spec = dataset_board(files, dataset, board, square_mm)
    bar = tqdm(total=2 + 3 * len(files["photos"]), desc="calibrate dataset", unit="step", disable=not progress)
    timings: dict = {}
    if executor is None:
        tick = time.perf_counter()
        intrinsics = intrinsics_from_boards(files["boards"], board_spec, progress=False, model=model)
        timings["intrinsics_s"] = time.perf_counter() - tick
        bar.update()
        tick = time.perf_counter()
        response = response_from_bracket(files["brackets"], progress=False)
        timings["response_s"] = time.perf_counter() - tick
        bar.update()
        results = fit_photos(files["photos"], spec, intrinsics, inverse_response(response), settings, bar, timings)
    else:
        shared = (executor.submit(timed, intrinsics_from_boards, files["boards"], board_spec, False, model),
                  executor.submit(timed, response_from_bracket, files["brackets"], False))
        (intrinsics, timings["intrinsics_s"]), (response, timings["response_s"]) = (f.result() for f in shared)
        bar.update(2)
        results = fit_photos_on(executor, files["photos"], spec, intrinsics, response, settings, bar, timings)
    tick = time.perf_counter()
    vignetting, results = vignetting_stage(results)
    timings["vignetting_s"] = time.perf_counter() - tick
    bar.close()
    timings["total_s"] = time.perf_counter() - started
    lens_digest = lens_uncertainty_summary(intrinsics, spec, results) if intrinsics else {}
    record = calibration_record(dataset, scene, spec, files, intrinsics, lens_digest, response, results, settings, board_spec,
                                timings)
    record["vignetting"] = vignetting
    write_calibration(out, record, spec, results, intrinsics, response)
    return record


def inverse_response(response: dict | None) -> Callable[[np.ndarray], np.ndarray] | None:
    """From normalised value to normalised irradiance, by the bracket's response curve (None without one)."""
    if response is None or "points" not in response:
        return None
    points = np.asarray(response["points"], float)
    return lambda v: np.interp(v, points[:, 1], points[:, 0]).astype(np.float32)


def fit_photos(photos: list[Path], spec, intrinsics: dict | None, inverse: Callable[[np.ndarray], np.ndarray] | None,
               settings: PoseSettings, bar, timings: dict) -> dict:
    """Each photo's PoseResult by file name; the first fixes the intrinsics when no boards did."""
    model = scene_model(spec)
    renderer = None
    known = None if intrinsics is None else held_intrinsics(intrinsics)
    results = {}
    for path in photos:
        tick = time.perf_counter()
        photo = read_photo(path, inverse if path.suffix.lower() not in RAW_SUFFIXES else None)
        check_photo(photo)
        start = start_camera(spec, photo, known)
        if renderer is None and settings.render_check:
            renderer = fit_renderer(spec, start, settings.render_spp)
        unknowns = Unknowns(intrinsics=known is None, radial=FREE_RADIAL_TERMS if known is None else 0)
        result = fit_photo(photo, model, start, unknowns, settings, renderer, bar, known.get("std") if known else None)
        if known is None:  # no boards: this photo's intrinsics hold for the rest
            known = _known_from(result, path)
        results[path.name] = result
        timings[f"pose_{path.name}_s"] = time.perf_counter() - tick
    return results


def _known_from(result: PoseResult, path: Path) -> dict:
    """The intrinsics a photo's fit (intrinsics free) fixes for the dataset's other photos."""
    c = result.camera
    return {"width": c.width, "height": c.height, "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy, "model": c.model,
            "xi": c.xi, "dist": tuple(c.dist), "source": f"fitted on {path.name}",
            "std": {k: result.std[k] for k in ("fx", "fy", "cx", "cy", "dist")}}


def fit_one_photo(path: Path, spec, known: dict | None, response: dict | None, settings: PoseSettings,
                  renderer_camera: CameraModel | None = None) -> tuple[PoseResult, CameraModel, float]:
    """One photo's pose as fit_photos fits it, on a dask worker: (its PoseResult, its start camera, seconds).
    The render check's renderer is built from ``renderer_camera`` (default: the photo's start camera), the
    first photo's start camera in fit_photos, so that each photo's render check renders what it renders there."""
    tick = time.perf_counter()
    photo = read_photo(path, inverse_response(response) if path.suffix.lower() not in RAW_SUFFIXES else None)
    check_photo(photo)
    start = start_camera(spec, photo, known)
    renderer = fit_renderer(spec, renderer_camera or start, settings.render_spp) if settings.render_check else None
    unknowns = Unknowns(intrinsics=known is None, radial=FREE_RADIAL_TERMS if known is None else 0)
    result = fit_photo(photo, scene_model(spec), start, unknowns, settings, renderer, None,
                       known.get("std") if known else None)
    return result, start, time.perf_counter() - tick


def fit_photos_on(executor, photos: list[Path], spec, intrinsics: dict | None, response: dict | None,
                  settings: PoseSettings, bar, timings: dict) -> dict:
    """fit_photos with each photo's pose a task on ``executor`` (one Mitsuba render at a time per worker:
    workbench.core.executor.run_alone): all at once when the intrinsics are known; without them the first
    photo's fit fixes them, so it runs first and the others after it."""
    known = None if intrinsics is None else held_intrinsics(intrinsics)
    results: dict = {}
    rest, renderer_camera = list(photos), None
    if known is None:
        first, rest = rest[0], rest[1:]
        result, renderer_camera, seconds = executor.submit(fit_one_photo, first, spec, None, response, settings,
                                                           alone=True).result()
        known = _known_from(result, first)
        results[first.name], timings[f"pose_{first.name}_s"] = result, seconds
        bar.update(3)
    futures = {path: executor.submit(fit_one_photo, path, spec, known, response, settings, renderer_camera, alone=True)
               for path in rest}  # with known intrinsics every photo's start camera is the first's (same size)
    for path, future in futures.items():
        result, _start, seconds = future.result()
        results[path.name], timings[f"pose_{path.name}_s"] = result, seconds
        bar.update(3)
    return results


def lens_uncertainty_summary(intrinsics: dict, spec, results: dict) -> dict:
    """calibration.json's digest of intrinsics.json's projection uncertainty and cross-validation
    (calibration.intrinsics.projection_uncertainty): the map's std at the centre, corners and median, and over each
    photo's CD (its top's annulus as calibration.pose.fringe_rotation.cd_mask draws it at the fitted camera), the
    diff's medians."""
    unc, cross = intrinsics.get("projection_uncertainty") or {}, intrinsics.get("cross_validation") or {}
    out: dict = {}
    if "std_px" in unc:
        out["projection_uncertainty_px"] = unc["std_px"]
    if "map_px" in unc and spec.cds:
        model = scene_model(spec)
        out["projection_uncertainty_cd_px"] = {name: map_over(unc["map_px"], cd_mask(model, r.camera, 0.0))
                                               for name, r in results.items()}
    if "diff_px" in cross:
        out["cross_validation"] = {"diff_median_px": cross["diff_px"]["median"],
                                   "predicted_median_px": cross["predicted_px"]["median"],
                                   "pooled_ratio": cross["splits"]["pooled_ratio"], "too_poor": cross.get("too_poor")}
    return out


def held_intrinsics(intrinsics: dict) -> dict:
    """intrinsics.json's record as the pose fit holds it: the pinhole's dist padded to its five
    coefficients (older files wrote four), every other lens model's as written."""
    dist = list(intrinsics["dist"])
    if intrinsics.get("model", "pinhole") == "pinhole":
        dist = (dist + [0.0] * 5)[:5]
    return dict(intrinsics, dist=tuple(dist))

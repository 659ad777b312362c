"""Intrinsics from board photographs: ``workbench calibrate intrinsics``.

[Zhang 2000], as implemented by OpenCV's ``calibrateCameraExtended`` (OpenCV's
distortion model [k1, k2, p1, p2, k3]; k3 held at 0 by default, as the wide-angle term is
not observable from a few boards). calibrateCameraExtended also gives the parameters'
standard deviations (from the Jacobian at the optimum, scaled by the residual) and each
view's RMS reprojection error.

Views: any photograph calibration.raw.decode reads (raw, 8/16-bit JPEG/PNG/TIFF, grey or
colour). Corners: calibration.board.corners (checkerboards) or calibration.board.charuco. A view
whose board is not found is reported and skipped; so is a view whose checker pattern
goes on past the requested corners, and when that happens in more than a quarter of the
views the board size is wrong and the calibration stops. At least MIN_VIEWS (3) usable
views calibrate; under FEW_VIEWS (6) the result carries a warning (intrinsics.json
``warnings``, the command's summary line) and the standard deviations that few views give.
Outlier views are left out by calibration.intrinsics.fit (in-sample rule among many views,
leave-one-out among few, never below MIN_VIEWS).

Lens models (renderer.lens: pinhole, rational, fisheye, omnidir; calibration.intrinsics.lens_models fits
each): ``model`` names one, or ``auto`` chooses by held-out views (calibration.intrinsics.lens_choice) and
records the scores and why in intrinsics.json ``model_choice``. Outlier views are then left out
under the chosen model.

Uncertainty (calibration.intrinsics.projection_uncertainty, mrcal's practice): the chosen model's projection
uncertainty map and cross-validation diff, in intrinsics.json ``projection_uncertainty`` and
``cross_validation`` and as 16-bit PNGs beside it (OUT.projection_uncertainty.png,
OUT.cross_validation_diff.png); a model too poor for the data is a warning.

Distortion terms: OpenCV's flags bound them; the command's ``--no-tangential`` holds p1, p2
at 0 (CALIB_ZERO_TANGENT_DIST) and ``--fit-k3`` lets k3 be fitted, so a calibration can use the
same model as another tool's (BoofCV's "radial 2, tangential false" is k1, k2 alone). Within that
bound the terms are chosen by held-out views (calibration.intrinsics.lens_choice.choose_terms; ``terms="all"``
fits every term the flags free, as OpenCV does; a set whose cross-validation diff flags it as too
poor for the data gives way to the first richer set that is not, ``_fit_accepted_terms``):
intrinsics.json ``model_choice.terms`` gives the candidates, their scores and the chosen set; the
fit, its standard deviations (0 for a held term), the outlier rule and the uncertainty maps are
the chosen set's. With fewer than FEW_VIEWS views the choice may take the centre prior (the
principal point held at the image centre with a stated std, lens_choice's module docstring):
intrinsics.json ``priors`` and ``std.priors`` say so, the command's summary prints it, and the
stds include the prior's. A fit whose projection folds back inside the image is warned of.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from tqdm import tqdm

from calibration.board.charuco import CharucoSpec, charuco_board, find_charuco_corners
from calibration.board.corners import find_board_corners, validate_pattern
from calibration.board.images import grey_unit
from calibration.intrinsics.fit import CRITERIA, FEW_VIEWS, MIN_VIEWS, fit_without_outliers, held_out_rms
from calibration.intrinsics.lens_choice import ModelChoice, TermChoice, choose_model, choose_terms
from calibration.intrinsics.lens_models import (
    CENTRE_PRIOR_FLAGS,
    MODEL_CHOICES,
    centre_prior,
    fold_reason,
    with_prior_std,
)
from calibration.intrinsics.projection_uncertainty import (
    PNG_SCALE,
    POOR_RATIO,
    Camera,
    ProjectionUncertainty,
    assess,
    write_map_png,
)
from calibration.raw.decode import decode, versions
from renderer.lens import LENS_MODELS
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text

__all__ = ["CRITERIA", "FEW_VIEWS", "MIN_VIEWS", "Calibration", "ViewReport", "board_points", "calibrate_board_views",
           "distortion_difference_px", "write_intrinsics"]

WRONG_SIZE_FRACTION = 0.25  # views whose pattern goes on past the grid, beyond which the board size is wrong
POOR_FOCAL_REL = 0.01       # a focal length known to worse than 1 % (one std) is worth a warning: tilt the board more
FLAG_NAMES = ("CALIB_USE_INTRINSIC_GUESS", "CALIB_FIX_ASPECT_RATIO", "CALIB_FIX_PRINCIPAL_POINT",
              "CALIB_ZERO_TANGENT_DIST", "CALIB_FIX_FOCAL_LENGTH", "CALIB_FIX_K1", "CALIB_FIX_K2", "CALIB_FIX_K3")
UNSUPPORTED_FLAGS = ("CALIB_RATIONAL_MODEL", "CALIB_THIN_PRISM_MODEL", "CALIB_TILTED_MODEL")
TERM_RULES = ("auto", "all")  # distortion terms chosen by held-out views, or every term the flags free


@dataclass
class ViewReport:
    file: str
    found: bool
    rms_px: float | None = None
    used: bool = False
    corners: int = 0
    detector: str = ""
    note: str = ""               # why a view is not used, or what was odd about it


@dataclass
class Calibration:
    K: np.ndarray                        # 3 x 3 camera matrix (pixels)
    dist: np.ndarray                     # the model's coefficients (pinhole: [k1, k2, p1, p2, k3])
    std: dict[str, Any]                  # standard deviations: fx, fy, cx, cy, dist
    rms_px: float                        # RMS reprojection error over the used views' corners
    width: int
    height: int
    views: list[ViewReport]
    flags: int
    image_points: list[np.ndarray]       # used views' corners (N, 1, 2)
    object_points: list[np.ndarray]      # and their board points (N, 3), metres
    timings: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)   # what the user should know (few views, a kept outlier)
    model: str = "pinhole"               # renderer.lens.LENS_MODELS
    xi: float = 0.0                      # Mei's xi (omnidir)
    choice: ModelChoice | None = None    # how --model auto chose
    uncertainty: ProjectionUncertainty | None = None   # the projection uncertainty map and cross-validation diff
    terms: TermChoice | None = None      # which distortion terms were fitted, and why
    priors: dict[str, Any] = field(default_factory=dict)   # priors the fit took (lens_models.centre_prior), if any

    @property
    def found(self) -> list[str]:
        return [v.file for v in self.views if v.found]

    @property
    def missed(self) -> list[str]:
        return [v.file for v in self.views if not v.found]

    def to_json(self) -> dict[str, Any]:
        K = self.K
        return {"width": self.width, "height": self.height, "fx": float(K[0, 0]), "fy": float(K[1, 1]),
                "cx": float(K[0, 2]), "cy": float(K[1, 2]), "dist": [float(d) for d in self.dist], "std": self.std,
                "rms_px": self.rms_px, "views": [asdict(v) for v in self.views], "flags": flag_names(self.flags),
                "warnings": list(self.warnings), "model": self.model,
                "coefficients": list(LENS_MODELS[self.model].coefficients),
                **({"xi": float(self.xi)} if self.model == "omnidir" else {}),
                **self._choice_json(), **({"priors": self.priors} if self.priors else {}),
                **(self.uncertainty.to_json() if self.uncertainty is not None else {})}


    def _choice_json(self) -> dict[str, Any]:
        """``model_choice``: how the model was chosen (or that it was asked for) and its terms."""
        if self.choice is None and self.terms is None:
            return {}
        record = self.choice.to_json() if self.choice is not None else {"model": self.model, "why": "as asked (--model)"}
        return {"model_choice": record | ({"terms": self.terms.to_json()} if self.terms is not None else {})}


def board_points(inner_corners: tuple[int, int], square_size_m: float) -> np.ndarray:
    """A checkerboard's inner corners in its own frame (N, 3), metres: origin at the board's
    centre, z = 0, row by row as OpenCV's detectors list them."""
    cols, rows = inner_corners
    j, i = np.mgrid[0:rows, 0:cols]
    s = square_size_m
    return np.stack([(i - (cols - 1) / 2) * s, (j - (rows - 1) / 2) * s, np.zeros_like(i, float)], -1).reshape(-1, 3)


def flag_names(flags: int) -> list[str]:
    return [name for name in FLAG_NAMES if flags & getattr(cv2, name)]


def _check_flags(flags: int, model: str, terms: str = "auto") -> None:
    if model not in MODEL_CHOICES:
        raise UserInputError("unknown lens model", field="--model", expected=f"one of {', '.join(MODEL_CHOICES)}",
                             got=model)
    if terms not in TERM_RULES:
        raise UserInputError("unknown rule for the distortion terms", field="terms",
                             expected=f"one of {', '.join(TERM_RULES)}", got=terms)
    for name in UNSUPPORTED_FLAGS:
        if flags & getattr(cv2, name):
            raise UserInputError("lens models are chosen by name (the rational model: model='rational'), not by flags",
                                 field="flags", got=name)


def _load_grey(path: Path) -> np.ndarray:
    return grey_unit(decode(path).pixels, where=str(path))


@dataclass
class _View:
    report: ViewReport
    corners: np.ndarray               # (N, 1, 2) pixels (N = 0 where the board was not found)
    points: np.ndarray                # (N, 3) board points, metres
    continues: bool = False           # the checker pattern goes on past the grid

    @property
    def usable(self) -> bool:
        return self.report.found and not self.continues


def _find_in_view(grey: np.ndarray, path: Path, board_size: tuple[int, int], checker_points: np.ndarray | None,
                  board: cv2.aruco.CharucoBoard | None) -> _View:
    continues: tuple[str, ...] = ()
    if board is not None:
        charuco = find_charuco_corners(grey, board)
        ok, corners, points = charuco.found, charuco.corners, charuco.object_points
        detector, unrefined = charuco.detector, charuco.unrefined
    else:
        checker = find_board_corners(grey, board_size)
        ok, corners, points, continues = checker.found, checker.corners, checker_points, checker.continues
        detector, unrefined = checker.detector, checker.unrefined
    notes = []
    if continues:
        notes.append("the checker pattern goes on past the grid's " + " and ".join(continues))
    if unrefined:
        notes.append(f"{unrefined} corners kept at the detector's estimate")
    if corners is None or points is None:
        corners, points = np.zeros((0, 1, 2), np.float32), np.zeros((0, 3), np.float32)
    report = ViewReport(str(path), ok, detector=detector, corners=len(corners), note="; ".join(notes))
    return _View(report, corners, points, bool(continues))


def _detect_views(paths: Sequence[Path], board_size: tuple[int, int], square_size_m: float,
                  charuco: CharucoSpec | None, image_size: tuple[int, int] | None,
                  progress: bool) -> tuple[list[_View], tuple[int, int]]:
    """Every view's corners, and the views' common size (width, height)."""
    board = charuco_board(board_size, square_size_m, charuco) if charuco else None
    checker_points = None if charuco else board_points(board_size, square_size_m).astype(np.float32)
    size = image_size
    views = []
    for path in tqdm(paths, desc="board views", unit="view", disable=not progress):
        grey = _load_grey(path)
        shape = (grey.shape[1], grey.shape[0])
        if size is None:
            size = shape
        elif shape != tuple(size):
            raise UserInputError("the views differ in size: all must come from one camera at one resolution",
                                 file=path, expected=f"{size[0]} x {size[1]} pixels", got=f"{shape[0]} x {shape[1]}")
        views.append(_find_in_view(grey, path, board_size, checker_points, board))
    assert size is not None
    return views, (int(size[0]), int(size[1]))


def _check_enough_views(views: list[_View], what: str) -> None:
    """A wrong board size (the pattern goes on in many views) or too few usable views is the user's error."""
    found = [v for v in views if v.report.found]
    continuing = [Path(v.report.file).name for v in found if v.continues]
    if continuing and len(continuing) > WRONG_SIZE_FRACTION * len(found):
        raise UserInputError(f"the board has more squares than {what}: in {len(continuing)} of {len(found)} views the "
                             "checker pattern goes on past the corners found", field="--board",
                             expected="the board's inner corners, COLSxROWS", got=continuing)
    usable = sum(v.usable for v in views)
    if usable < MIN_VIEWS:
        missed = [Path(v.report.file).name for v in views if not v.report.found]
        raise UserInputError(f"the board ({what}) was found in {usable} of {len(views)} views; calibration needs "
                             f"at least {MIN_VIEWS} (check --board and --square-mm)", field="IMAGE",
                             got={"not found": missed} if missed else None)


def _calibrate_without_outliers(views: list[_View], size: tuple[int, int], flags: int, model: str,
                                terms: tuple[str, ...] | None = None):
    """calibration.intrinsics.fit.fit_without_outliers on the views' corners; the views' reports
    get their RMS, whether used and why not. Returns the fit, the views used and warnings."""
    robust = fit_without_outliers([v.points for v in views], [v.corners for v in views], size, flags, model, terms)
    for index, note in robust.notes.items():
        report = views[index].report
        report.note = "; ".join(n for n in (report.note, note) if n)
    used = [views[i] for i in robust.kept]
    for view, error in zip(used, robust.fit.per_view_px, strict=True):
        view.report.used, view.report.rms_px = True, float(error)
    warnings = [f"{Path(views[i].report.file).name} fits to {error:.2f} px RMS, perhaps an outlier, but with "
                f"{MIN_VIEWS} views (the least that determine the intrinsics) none can be left out: add views"
                for i, error in robust.suspects.items()]
    return robust.fit, used, warnings


def _fit_terms(views: list[_View], size: tuple[int, int], flags: int, model: str, terms: tuple[str, ...] | None,
               with_uncertainty: bool, prior: bool = False):
    """One fit of ``terms`` without outlier views (the views' reports updated), the held-out RMS of the
    views left out, warnings, and its uncertainty (or None). ``prior``: the principal point held at the
    image centre, its prior std carried into the others' (calibration.intrinsics.lens_models.with_prior_std).
    A fit whose projection folds back inside the image (lens_models.fold_reason) is warned of."""
    flags = flags | (CENTRE_PRIOR_FLAGS if prior else 0)
    fit, used, warnings = _calibrate_without_outliers([v for v in views if v.usable], size, flags, model, terms)
    if prior:
        fit = with_prior_std(fit, [v.points for v in used], [v.corners for v in used], size, flags)
    for view in views:
        if view.usable and not view.report.used:
            view.report.rms_px = held_out_rms(view.points, view.corners, fit.K, fit.dist, fit.model, fit.xi)
    folds = fold_reason(fit, size)
    warnings = _few_view_warnings(len(used), fit.K, fit.std) + warnings + ([folds] if folds else [])
    uncertainty = assess(Camera(model, fit.K, fit.dist, fit.xi, fit.terms), [v.points for v in used],
                         [v.corners for v in used], size, flags) if with_uncertainty else None
    return fit, used, warnings + (uncertainty.warnings if uncertainty is not None else []), uncertainty


def _too_poor(result) -> bool:
    uncertainty = result[3]
    return uncertainty is not None and uncertainty.cross_validation is not None and uncertainty.cross_validation.too_poor


def _fit_accepted_terms(views: list[_View], size: tuple[int, int], flags: int, model: str, choice: TermChoice | None,
                        with_uncertainty: bool):
    """``_fit_terms`` of the chosen terms; where the cross-validation finds them too poor for the data
    (calibration.intrinsics.projection_uncertainty.POOR_RATIO) and a richer candidate's is not, the first such set
    instead, as the held-out rule's POOR_RMS_PX does for the RMS [mrcal: the cross-validation diff flags a
    model too lean for the data; measured on OpenCV's right*.jpg: k1, k2 held out 0.5 % better, pooled
    ratio 3.2, and with p1, p2 1.57]. Candidates the term choice rejected (not fitted, or folding back
    inside the image) are not tried. Noted in ``choice``; where every richer set is too poor as well, or
    there is none, the chosen fit stays (with the warning), its views' records as that fit left them."""
    before = [(v.report.note, v.report.used, v.report.rms_px) for v in views]
    result = _fit_terms(views, size, flags, model, choice.chosen if choice else None, with_uncertainty,
                        choice is not None and choice.prior)
    if choice is None or not choice.held_out or not _too_poor(result):
        return result
    first, after = result, [(v.report.note, v.report.used, v.report.rms_px) for v in views]
    chosen = choice.name(choice.index)
    ratios = {chosen: result[3].cross_validation.ratio}
    for k in range(choice.index + 1, len(choice.candidates)):
        score = choice.scores[k]
        if score is None or not np.isfinite(score):
            continue
        _restore(views, before)
        result = _fit_terms(views, size, flags, model, choice.candidates[k], with_uncertainty, choice.priors[k])
        cross = result[3].cross_validation if result[3] is not None else None
        if cross is None:
            break
        ratios[choice.name(k)] = cross.ratio
        if not cross.too_poor:
            choice.why += (f"; but the cross-validation finds {chosen} too poor for the data (pooled ratio "
                           f"{ratios[chosen]:.2f} over {POOR_RATIO:g}) and {choice.name(k)} not ({cross.ratio:.2f}): "
                           f"{choice.name(k)} fitted")
            choice.choose(k)
            choice.cross_validation = ratios
            return result
    _restore(views, after)
    choice.cross_validation = ratios
    choice.why += (f"; the cross-validation finds every richer set too poor as well ({_ratios(ratios)})" if len(ratios) > 1
                   else f"; the cross-validation finds {chosen} too poor for the data, and there is no richer set to try")
    return first


def _ratios(ratios: dict[str, float]) -> str:
    return ", ".join(f"{name} {ratio:.2f}" for name, ratio in ratios.items())


def _restore(views: list[_View], reports: list[tuple[str, bool, float | None]]) -> None:
    for view, (note, used, rms) in zip(views, reports, strict=True):
        view.report.note, view.report.used, view.report.rms_px = note, used, rms


def _few_view_warnings(used: int, K: np.ndarray, std: np.ndarray) -> list[str]:
    """Warnings on how well the views determine the camera: fewer than FEW_VIEWS views, or fx
    known to worse than POOR_FOCAL_REL."""
    warnings = []
    fx_rel = float(std[0] / K[0, 0])
    if used < FEW_VIEWS:
        warnings.append(f"only {used} views used (fewer than {FEW_VIEWS}): the intrinsics rest on few board poses "
                        f"(fx +- {100 * fx_rel:.2f} %) and an outlier view is harder to find; add views at other tilts")
    elif fx_rel > POOR_FOCAL_REL:
        warnings.append(f"fx is determined to +- {100 * fx_rel:.2f} % only: add views with the board tilted more")
    return warnings


def calibrate_board_views(paths: Sequence[str | Path], board_size: tuple[int, int], square_size_m: float,
                          image_size: tuple[int, int] | None = None, flags: int = cv2.CALIB_FIX_K3, *,
                          charuco: CharucoSpec | None = None, progress: bool = False,
                          model: str = "pinhole", with_uncertainty: bool = True, terms: str = "auto") -> Calibration:
    """Find the board in each view and calibrate.

    ``board_size``: inner corners (cols, rows) of a checkerboard, or with ``charuco`` the
    board's squares (cols, rows) as OpenCV's CharucoBoard counts them. ``square_size_m``:
    the side of a square. ``image_size``: (width, height) every view must have (default: the
    first view's). Needs the board in at least MIN_VIEWS views; warns under FEW_VIEWS.
    ``model``: a lens model of renderer.lens, or ``auto`` (calibration.intrinsics.lens_choice).
    ``with_uncertainty``: the projection uncertainty map and the cross-validation diff
    (calibration.intrinsics.projection_uncertainty) of the chosen model, under ``uncertainty``. ``terms``:
    ``auto`` chooses the distortion terms by held-out views (calibration.intrinsics.lens_choice.choose_terms),
    ``all`` fits every term the flags free.
    """
    start = time.perf_counter()
    if not charuco:
        board_size = validate_pattern(board_size)
    if not square_size_m > 0:
        raise UserInputError("the square size must be positive", field="--square-mm", got=square_size_m)
    _check_flags(flags, model, terms)
    files = [Path(p) for p in paths]
    if not files:
        raise UserInputError("no views given", field="IMAGE")
    views, size = _detect_views(files, board_size, square_size_m, charuco, image_size, progress)
    detected_s = time.perf_counter() - start
    what = (f"{board_size[0]} x {board_size[1]} squares (ChArUco)" if charuco
            else f"{board_size[0]} x {board_size[1]} inner corners")
    _check_enough_views(views, what)
    choice, term_choice = _choose([v for v in views if v.usable], size, flags, model, terms)
    model = choice.model if choice is not None else model
    fit, used, warnings, uncertainty = _fit_accepted_terms(views, size, flags, model, term_choice, with_uncertainty)
    prior = term_choice is not None and term_choice.prior
    K, dist, std = fit.K, fit.dist, fit.std
    uncertainty_s = uncertainty.seconds if uncertainty is not None else 0.0
    fitted_s = time.perf_counter() - start - detected_s - uncertainty_s
    std_json = {"fx": float(std[0]), "fy": float(std[1]), "cx": float(std[2]), "cy": float(std[3]),
                "dist": [float(s) for s in std[4:]], **({"xi": fit.xi_std} if model == "omnidir" else {}),
                **({"priors": ["principal_point"]} if prior else {})}
    timings = {"detection_s": detected_s, "calibration_s": fitted_s,
               "uncertainty_s": uncertainty_s,
               "total_s": time.perf_counter() - start}
    return Calibration(K, dist, std_json, fit.rms_px, size[0], size[1], [v.report for v in views],
                       flags | (CENTRE_PRIOR_FLAGS if prior else 0), [v.corners for v in used], [v.points for v in used],
                       timings, warnings, model, fit.xi, choice, uncertainty, term_choice,
                       centre_prior(size) if prior else {})


def _choose(usable: list[_View], size: tuple[int, int], flags: int, model: str, terms: str):
    """The model (``auto``: calibration.intrinsics.lens_choice.choose_model, which chooses every scored model's
    terms on the same folds) and its term choice (``terms="auto"``; None for ``all``)."""
    points, corners = [v.points for v in usable], [v.corners for v in usable]
    choice = choose_model(points, corners, size, flags) if model == "auto" else None
    model = choice.model if choice is not None else model
    if terms != "auto":
        return choice, None
    known = choice.terms.get(model) if choice is not None else None
    return choice, known if known is not None else choose_terms(points, corners, size, flags, model)


def _write_maps(uncertainty: ProjectionUncertainty, out: Path, record: dict[str, Any]) -> None:
    """The projection uncertainty map and the first split's cross-validation diff as 16-bit PNGs beside
    ``out`` (OUT.projection_uncertainty.png, OUT.cross_validation_diff.png), named in ``record``."""
    scale = f"grid-node values: px = value / {PNG_SCALE:g}; 65535 = over range or no ray through the pixel"
    maps = [("projection_uncertainty", uncertainty.map.std_px)]
    if uncertainty.cross_validation is not None:
        maps.append(("cross_validation", uncertainty.cross_validation.splits[0].diff_px))
    for key, values in maps:
        name = f"{out.stem}.{'cross_validation_diff' if key == 'cross_validation' else key}.png"
        write_map_png(out.with_name(name), values)
        record[key].update({"image": name, "image_scale": scale})


def write_intrinsics(calibration: Calibration, out: str | Path, settings: dict[str, Any]) -> dict[str, Any]:
    """intrinsics.json: the result, the settings, versions and timings; written atomically. With
    the calibration's uncertainty, its maps beside it (``_write_maps``)."""
    record = {**calibration.to_json(), "settings": settings, "versions": versions(), "timings": calibration.timings}
    if calibration.uncertainty is not None:
        _write_maps(calibration.uncertainty, Path(out), record)
    atomic_write_text(out, json.dumps(record, indent=2) + "\n")
    return record


def distortion_difference_px(K: np.ndarray, dist_a, dist_b, size: tuple[int, int], covered: np.ndarray | None = None,
                             step: float = 4.0) -> float:
    """Largest distance between where two distortion models put a point, both with camera
    matrix K: every pixel of a grid over the image (or over the convex hull of
    ``covered``, pixels) is undistorted with ``dist_a`` and distorted again with ``dist_b``."""
    u, v = np.meshgrid(np.arange(0, size[0], step), np.arange(0, size[1], step))
    pixels = np.stack([u.ravel(), v.ravel()], 1).astype(float)
    if covered is not None:
        hull = cv2.convexHull(np.asarray(covered, np.float32).reshape(-1, 1, 2))
        pixels = pixels[[cv2.pointPolygonTest(hull, (float(x), float(y)), False) >= 0 for x, y in pixels]]
    rays = cv2.undistortPoints(pixels.reshape(-1, 1, 2), K, np.asarray(dist_a, float),
                               criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)).reshape(-1, 2)
    again, _ = cv2.projectPoints(np.c_[rays, np.ones(len(rays))], np.zeros(3), np.zeros(3), K, np.asarray(dist_b, float))
    return float(np.max(np.linalg.norm(again.reshape(-1, 2) - pixels, axis=1)))

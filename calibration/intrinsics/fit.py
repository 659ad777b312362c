"""The intrinsics fit of ``workbench calibrate intrinsics``, from corners already found, with
outlier views left out.

[Zhang 2000], as implemented by OpenCV's ``calibrateCameraExtended`` (OpenCV documentation,
calib3d, "calibrateCamera"): the parameters' standard deviations come from the Jacobian at
the optimum, scaled by the residual variance over the degrees of freedom left (corner
coordinates minus intrinsics and six pose parameters per view), so few views give the larger
uncertainty they should. Three views in general position determine the five intrinsics of a
pinhole camera [Zhang 2000, Sec. 3.1]; hence MIN_VIEWS = 3.

Outlier views (a view taken at another zoom setting, a board that bent, corners the detector
misplaced), two rules:

* FEW_VIEWS views or more: while the worst view's in-sample RMS is above OUTLIER_FACTOR times
  the median view's (and above OUTLIER_FLOOR_PX), it is dropped and the fit repeated. Among
  many views one view's leverage is small, so the view that does not belong is the worst fit.
* Fewer (4 or 5): one view's leverage is large, and a bad view pulls the intrinsics until its
  misfit is spread over the others (measured, views at fx 520 px and one at a 3 % longer
  focal length among four: in-sample that view is not even the worst, and fx comes out 7 %
  high). So each view is left out in turn (leave-one-out cross-validation [Stone 1974]); the
  view whose removal leaves the best-fitting rest is the candidate, and it is dropped when its
  held-out RMS (its own best pose under the rest's intrinsics) is above OUTLIER_FACTOR times
  the rest's median view RMS (and above OUTLIER_FLOOR_PX) and the rest fit REST_GAIN times
  better without it (pooled RMS of the other views, fitted with it over fitted without it). The
  second test keeps a good view whose removal leaves three views too alike to extrapolate to
  it (measured on OpenCV's right*.jpg, four-view subsets fitting tangential terms: such a rest
  gave fx 480 +- 9 px against 537 from 13 views, a held-out RMS over 0.5 px, and a gain of
  only 1.1; a view that does not belong gives 3 and more).

No rule drops below MIN_VIEWS views. With exactly MIN_VIEWS views neither rule applies (a bad
view spreads its misfit over the other two, and the median of three is no longer robust:
measured, a view through another lens fits to 0.87 px and the good ones to 0.40 px, where
they fit to 0.02 px without it), so the worst view is kept but named when its RMS is above
OUTLIER_FLOOR_PX.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from calibration.intrinsics.lens_models import Fit, fit_model, solve_pose
from workbench.core.errors import UserInputError

MIN_VIEWS = 3               # views that determine a pinhole camera's five intrinsics [Zhang 2000, Sec. 3.1]
FEW_VIEWS = 6               # below this many views: a warning, and the leave-one-out outlier rule
OUTLIER_FACTOR = 3.0        # a view whose RMS is this many times the median view's is an outlier ...
OUTLIER_FLOOR_PX = 0.5      # ... unless it is within half a pixel anyway (clean sets have no outliers to find)
REST_GAIN = 1.5             # few views: the others must fit this many times better without the view (see docstring)
CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)


@dataclass
class RobustFit:
    """A fit with outlier views left out: ``kept`` indexes the views given; ``notes`` says, per view
    index, why it was dropped or why it looks wrong but was kept (``suspects``: such views and their RMS, px)."""

    fit: Fit
    kept: list[int]
    notes: dict[int, str] = field(default_factory=dict)
    suspects: dict[int, float] = field(default_factory=dict)


def fit_views(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int], flags: int,
              model: str = "pinhole", terms: Sequence[str] | None = None) -> Fit:
    """[Zhang 2000] through cv2.calibrateCameraExtended for the pinhole (the other lens models:
    calibration.intrinsics.lens_models.fit_model): board points (N, 3) and their corners (N, 1, 2) per
    view, image ``size`` (width, height), OpenCV's calibration ``flags``, the coefficients
    ``terms`` fitted (default: those the flags leave free)."""
    return fit_model(points, corners, size, flags, model, terms)


def held_out_rms(points: np.ndarray, corners: np.ndarray, K: np.ndarray, dist: np.ndarray, model: str = "pinhole",
                 xi: float = 0.0) -> float:
    """A view's RMS reprojection error under intrinsics fitted without it, at its own best pose
    (calibration.intrinsics.lens_models.solve_pose: for the pinhole cv2.solvePnP, iterative
    Levenberg-Marquardt on the reprojection error)."""
    return solve_pose(model, points, corners, K, dist, xi)[0]


def _threshold(per_view_px: np.ndarray) -> float:
    return max(OUTLIER_FACTOR * float(np.median(per_view_px)), OUTLIER_FLOOR_PX)


def _why(rms_px: float, threshold_px: float, held_out: bool) -> str:
    kind = "held-out RMS (its pose under the other views' intrinsics)" if held_out else "RMS"
    return (f"outlier: {kind} {rms_px:.2f} px, over {threshold_px:.2f} px ({OUTLIER_FACTOR:g} x the median "
            f"view's, at least {OUTLIER_FLOOR_PX} px)")


def _pooled_rms(per_view_px: np.ndarray, counts: list[int]) -> float:
    return float(np.sqrt(np.sum(np.asarray(counts) * per_view_px**2) / np.sum(counts)))


@dataclass
class _Candidate:
    index: int            # the view left out
    rest: Fit             # the fit of the others
    held_out_px: float    # the view's RMS under the others' intrinsics
    threshold_px: float   # what it is held to
    gain: float           # the others' RMS under the fit with the view over theirs without it


def _leave_one_out(points: list[np.ndarray], corners: list[np.ndarray], size: tuple[int, int], flags: int,
                   whole: Fit) -> _Candidate | None:
    """The view whose removal leaves the best-fitting rest, with what the module docstring's
    few-view rule tests; None when no rest can be fitted. ``whole``: the fit of every view."""
    best: tuple[int, Fit] | None = None
    for k in range(len(points)):
        try:
            rest = fit_views(points[:k] + points[k + 1:], corners[:k] + corners[k + 1:], size, flags, whole.model,
                             whole.terms)
        except UserInputError:
            continue
        if best is None or rest.rms_px < best[1].rms_px:
            best = (k, rest)
    if best is None:
        return None
    k, rest = best
    counts = [len(c) for i, c in enumerate(corners) if i != k]
    gain = _pooled_rms(np.delete(whole.per_view_px, k), counts) / max(_pooled_rms(rest.per_view_px, counts), 1e-12)
    held_out = held_out_rms(points[k], corners[k], rest.K, rest.dist, rest.model, rest.xi)
    return _Candidate(k, rest, held_out, _threshold(rest.per_view_px), gain)


def _is_outlier(candidate: _Candidate | None) -> bool:
    return candidate is not None and candidate.held_out_px > candidate.threshold_px and candidate.gain > REST_GAIN


def fit_without_outliers(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int],
                         flags: int, model: str = "pinhole", terms: Sequence[str] | None = None) -> RobustFit:
    """Fit ``model`` (renderer.lens) with the coefficients ``terms`` (default: those the flags leave
    free), dropping outlier views by the module docstring's rules, never below MIN_VIEWS views."""
    if len(points) < MIN_VIEWS:
        raise UserInputError(f"calibration needs at least {MIN_VIEWS} board views, got {len(points)}", field="IMAGE")
    kept = list(range(len(points)))
    notes: dict[int, str] = {}
    current = fit_views(points, corners, size, flags, model, terms)
    while len(kept) > MIN_VIEWS:
        if len(kept) >= FEW_VIEWS:
            worst = int(np.argmax(current.per_view_px))
            threshold = _threshold(current.per_view_px)
            if current.per_view_px[worst] <= threshold:
                break
            notes[kept.pop(worst)] = _why(float(current.per_view_px[worst]), threshold, held_out=False)
            current = fit_views([points[i] for i in kept], [corners[i] for i in kept], size, flags, model, terms)
            continue
        found = _leave_one_out([points[i] for i in kept], [corners[i] for i in kept], size, flags, current)
        if found is None or not _is_outlier(found):
            break
        current = found.rest
        notes[kept.pop(found.index)] = (_why(found.held_out_px, found.threshold_px, held_out=True)
                                        + f"; without it the others fit {found.gain:.1f} x better")
    suspects = {}
    worst = int(np.argmax(current.per_view_px))
    if len(kept) == MIN_VIEWS and current.per_view_px[worst] > OUTLIER_FLOOR_PX:
        index, error = kept[worst], float(current.per_view_px[worst])
        notes[index] = (f"RMS {error:.2f} px, over {OUTLIER_FLOOR_PX} px: perhaps an outlier, kept as only "
                        f"{MIN_VIEWS} views remain")
        suspects[index] = error
    return RobustFit(current, kept, notes, suspects)

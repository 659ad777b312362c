"""Intrinsics fits of every lens model (renderer.lens), and the choice among them by held-out views.

Fits, from board points and their corners per view:

* ``pinhole`` and ``rational``: [Zhang 2000] through cv2.calibrateCameraExtended (the
  rational model with CALIB_RATIONAL_MODEL, k1..k6 all free); the standard deviations are
  OpenCV's (the Jacobian at the optimum, scaled by the residual variance).
* ``fisheye``: cv2.fisheye.calibrate [Kannala 2006] (skew held at 0, extrinsics recomputed
  each round); ``omnidir``: cv2.omnidir.calibrate [Mei 2007] (skew held at 0). Neither gives
  standard deviations: they are computed here as OpenCV does for the others, sigma^2 (J^T J)^-1
  with sigma^2 the residual sum of squares over the degrees of freedom, J the analytic
  Jacobian (renderer.lens.project_with_jacobian) over the intrinsics and every view's pose
  (xi's column by central differences).

Choice (``--model auto``), after mrcal's practice of judging a model by data it was not
fitted to: the views are split into CV_FOLDS folds; each model is fitted to the views of the
other folds and each held-out view is reprojected at its own best pose under those
intrinsics (``held_out_rms``); the pooled RMS over every held-out corner is the model's score.
MODEL_ORDER lists the models simplest first (by parameter count: pinhole 8 with k3 held,
fisheye 8, omnidir 9, rational 12); the choice is the simplest model whose score is not worse
than any richer model's by more than NOT_WORSE_REL (relative) and is not above POOR_RMS_PX
when a richer model scores better. With fewer than MIN_VIEWS + 1 views no fold can be held
out, and the in-sample RMS decides by the same rule, as the record says.

Distortion terms. ``terms`` names the coefficients a fit frees (the rest held at 0); by default
those the flags leave free (``allowed_terms``: the pinhole honours OpenCV's CALIB_FIX_K1..K3 and
CALIB_ZERO_TANGENT_DIST, the rational model those but k3, and CALIB_FIX_K4..K6; omnidir
CALIB_ZERO_TANGENT_DIST; fisheye none, the flags being the pinhole's). TERM_CANDIDATES lists each
model's nested candidate sets, simplest first, among which calibration.intrinsics.lens_choice chooses by the
same held-out rule. A held coefficient has no variance: its std is 0, as OpenCV reports a held k3.

The centre prior (few views; calibration.intrinsics.lens_choice offers it): the principal point held
at the image centre ((w - 1) / 2, (h - 1) / 2, where OpenCV's CALIB_FIX_PRINCIPAL_POINT holds it)
with a std of CENTRE_PRIOR_REL (2 %) of the image's width and height [Hartley 2004, Ch. 6: the
principal point is often near the image centre, and fixing it there is a common assumption]; the
publisher's calibrations of the two real 640 x 480 cameras in the project's data put it 1.1-1.7 % of
the width and 1.5-1.6 % of the height from the centre. Its std is carried into the others'
(``with_prior_std``). ``fold_reason``: whether a fit is physical (monotone out to the image's edge).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np
from scipy.optimize import least_squares

from renderer.lens import LENS_MODELS, normalized, project, project_with_jacobian
from workbench.core.errors import UserInputError

MODEL_ORDER = ("pinhole", "fisheye", "omnidir", "rational")   # simplest first (module docstring)
MODEL_CHOICES = ("auto", *MODEL_ORDER)
CV_FOLDS = 5                # held-out folds of the choice (fewer views: one view per fold)
NOT_WORSE_REL = 0.05        # a held-out RMS within 5 % of a richer model's is "not worse": fold noise is of that size
POOR_RMS_PX = 1.0           # never a model above this when a richer one does better (the rule)
FIT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
CENTRE_PRIOR_FLAGS = cv2.CALIB_FIX_PRINCIPAL_POINT   # the centre prior: OpenCV holds the principal point at the centre
CENTRE_PRIOR_REL = 0.02     # its std, per axis, as a fraction of the image's width and height (module docstring)
PRIOR_MODELS = ("pinhole", "rational")               # the models whose fit (calibrateCamera) honours that flag
FOLD_FIELD_DEG = 90.0       # fold_reason: the projection must be monotone to the image's edge or this far off axis
FOLD_STEPS = 600            # angles sampled by fold_reason
XI_STEP = 1e-6              # central-difference step of the omnidir Jacobian's xi column
TERM_CANDIDATES: dict[str, tuple[tuple[str, ...], ...]] = {   # nested free-coefficient sets, simplest first
    "pinhole": (("k1", "k2"), ("k1", "k2", "p1", "p2"), ("k1", "k2", "p1", "p2", "k3")),
    "rational": (("k1", "k2", "k3", "k4", "k5", "k6"), ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")),
    "fisheye": (("k1", "k2"), ("k1", "k2", "k3"), ("k1", "k2", "k3", "k4")),
    "omnidir": (("k1", "k2"), ("k1", "k2", "p1", "p2")),
}
HOLD_FLAGS = {"k1": cv2.CALIB_FIX_K1, "k2": cv2.CALIB_FIX_K2, "k3": cv2.CALIB_FIX_K3, "k4": cv2.CALIB_FIX_K4,
              "k5": cv2.CALIB_FIX_K5, "k6": cv2.CALIB_FIX_K6, "p1": cv2.CALIB_ZERO_TANGENT_DIST,
              "p2": cv2.CALIB_ZERO_TANGENT_DIST}   # calib3d's flag holding each coefficient (pinhole, rational)
WIDE_HOLD_FLAGS = {
    "fisheye": {"k1": cv2.fisheye.CALIB_FIX_K1, "k2": cv2.fisheye.CALIB_FIX_K2, "k3": cv2.fisheye.CALIB_FIX_K3,
                "k4": cv2.fisheye.CALIB_FIX_K4},
    "omnidir": {"k1": cv2.omnidir.CALIB_FIX_K1, "k2": cv2.omnidir.CALIB_FIX_K2, "p1": cv2.omnidir.CALIB_FIX_P1,
                "p2": cv2.omnidir.CALIB_FIX_P2},
}


@dataclass
class Fit:
    """One intrinsics fit of one lens model."""

    rms_px: float               # RMS reprojection error over every corner
    K: np.ndarray               # 3 x 3 camera matrix (pixels)
    dist: np.ndarray            # the model's coefficients (renderer.lens.LENS_MODELS)
    std: np.ndarray             # standard deviations of fx, fy, cx, cy, then of dist (zero where held)
    per_view_px: np.ndarray     # each view's RMS reprojection error
    model: str = "pinhole"
    xi: float = 0.0             # Mei's xi (omnidir only)
    xi_std: float = 0.0
    terms: tuple[str, ...] = ()   # the coefficients fitted (the others held at 0)


def allowed_terms(model: str, flags: int) -> tuple[str, ...]:
    """The coefficients the flags leave free, in the model's order (module docstring)."""
    names = LENS_MODELS[model].coefficients
    honoured = {"pinhole": set(names), "rational": set(names) - {"k3"}, "omnidir": {"p1", "p2"}}.get(model, set())
    return tuple(n for n in names if not (n in honoured and flags & HOLD_FLAGS[n]))


def _terms_of(model: str, flags: int, terms: Sequence[str] | None) -> tuple[str, ...]:
    names = LENS_MODELS[model].coefficients
    if terms is None:
        return allowed_terms(model, flags)
    unknown = [t for t in terms if t not in names]
    if unknown:
        raise ValueError(f"the {model} lens model has no coefficient {', '.join(unknown)} (it has {', '.join(names)})")
    return tuple(n for n in names if n in terms)


def intrinsic_free(model: str, terms: Sequence[str]) -> np.ndarray:
    """Which entries of the intrinsic vector (fx, fy, cx, cy, dist..., xi for omnidir) a fit of
    ``terms`` frees, before any flag holding the focal length or principal point."""
    names = LENS_MODELS[model].coefficients
    return np.r_[np.ones(4, bool), [n in terms for n in names], np.ones(int(model == "omnidir"), bool)].astype(bool)


def _calibration_failed(count: int, error: cv2.error | str) -> UserInputError:
    message = str(error).strip().splitlines()[-1] if str(error).strip() else "no solution"
    return UserInputError(f"the {count} board views do not determine the intrinsics (OpenCV: {message})",
                          field="IMAGE", expected="views of the board at several different tilts")


def _fit_opencv(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int], flags: int,
                model: str, terms: tuple[str, ...], start: Fit | None = None) -> Fit:
    count = LENS_MODELS[model].count
    if model == "rational":
        flags = (flags | cv2.CALIB_RATIONAL_MODEL) & ~cv2.CALIB_FIX_K3
    for name in LENS_MODELS[model].coefficients:
        if name not in terms:
            flags |= HOLD_FLAGS[name]
    try:
        rms, K, dist, _, _, std, _, per_view = cv2.calibrateCameraExtended(
            list(points), list(corners), size, np.eye(3) if start is None else start.K.copy(),
            np.zeros(count) if start is None else start.dist.copy(), flags=flags, criteria=FIT_CRITERIA)
    except cv2.error as error:
        raise _calibration_failed(len(points), error) from None
    return Fit(float(rms), K, dist.ravel()[:count], std.ravel()[:4 + count], per_view.ravel(), model, terms=terms)


def centre_prior(size: tuple[int, int]) -> dict[str, Any]:
    """The centre prior (module docstring) as intrinsics.json records it: where and how sure."""
    return {"principal_point": {"at_px": [(size[0] - 1) / 2, (size[1] - 1) / 2],
                                "std_px": [CENTRE_PRIOR_REL * size[0], CENTRE_PRIOR_REL * size[1]],
                                "why": "fewer views than determine it well: the held-out views chose the prior"}}


def with_prior_std(fit: Fit, points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int],
                   flags: int) -> Fit:
    """``fit`` (the principal point held at the image centre by the centre prior) with the prior's own
    uncertainty carried into the other parameters' standard deviations, as a consider parameter is
    [Bierman 1977, consider covariance]: the fit is repeated with the principal point moved by one prior
    std along each axis, and each parameter's change adds in quadrature to its std (first-order
    propagation of the prior's variance); cx, cy read the prior's std."""
    prior = centre_prior(size)["principal_point"]["std_px"]
    held = flags | cv2.CALIB_USE_INTRINSIC_GUESS | CENTRE_PRIOR_FLAGS
    base = np.r_[fit.K[0, 0], fit.K[1, 1], fit.K[0, 2], fit.K[1, 2], fit.dist]
    variance = fit.std[:len(base)] ** 2
    for axis, step in enumerate(prior):
        start = replace(fit, K=fit.K.copy())
        start.K[axis, 2] += step
        moved = _fit_opencv(points, corners, size, held, fit.model, fit.terms, start)
        change = np.r_[moved.K[0, 0], moved.K[1, 1], moved.K[0, 2], moved.K[1, 2], moved.dist] - base
        change[2:4] = 0.0
        variance = variance + change ** 2
    std = np.sqrt(variance)
    std[2:4] = prior
    return replace(fit, std=std)


def _pose_jacobian(model: str, points: Sequence[np.ndarray], corners: Sequence[np.ndarray], K: np.ndarray,
                   dist: np.ndarray, xi: float, poses: list[tuple[np.ndarray, np.ndarray]]):
    """Residuals (2N,) and the Jacobian (2N, intrinsics + 6 per view) of every view at its pose."""
    count = LENS_MODELS[model].count
    n_intrinsic = 4 + count + (model == "omnidir")
    rows = sum(2 * len(p) for p in points)
    jac = np.zeros((rows, n_intrinsic + 6 * len(points)))
    residuals = np.zeros(rows)
    row = 0
    for v, (pts, seen, (rvec, tvec)) in enumerate(zip(points, corners, poses, strict=True)):
        pixels, j = project_with_jacobian(model, pts, rvec, tvec, K, dist, xi)
        n = 2 * len(pts)
        residuals[row:row + n] = (pixels - np.asarray(seen, float).reshape(-1, 2)).ravel()
        jac[row:row + n, :4 + count] = j[:, 6:10 + count]
        if model == "omnidir":
            ahead = project(model, pts, rvec, tvec, K, dist, xi + XI_STEP)
            back = project(model, pts, rvec, tvec, K, dist, xi - XI_STEP)
            jac[row:row + n, 4 + count] = ((ahead - back) / (2 * XI_STEP)).ravel()
        jac[row:row + n, n_intrinsic + 6 * v:n_intrinsic + 6 * v + 6] = j[:, :6]
        row += n
    return residuals, jac, n_intrinsic


def _free_columns(jac: np.ndarray, n_intrinsic: int, free: np.ndarray) -> np.ndarray:
    """The Jacobian's columns of the free intrinsics, then every pose's."""
    return np.hstack([jac[:, :n_intrinsic][:, free], jac[:, n_intrinsic:]])


def _standard_deviations(model: str, points, corners, K, dist, xi, poses, free: np.ndarray) -> tuple[np.ndarray, float]:
    """sigma^2 (J^T J)^-1 at the optimum over the free intrinsics and every pose (module docstring):
    (std of fx, fy, cx, cy, dist...; 0 where held), std of xi."""
    residuals, jac, n_intrinsic = _pose_jacobian(model, points, corners, K, dist, xi, poses)
    jac = _free_columns(jac, n_intrinsic, free)
    dof = max(len(residuals) - jac.shape[1], 1)
    sigma2 = float(residuals @ residuals) / dof
    try:
        cov = np.linalg.inv(jac.T @ jac) * sigma2
    except np.linalg.LinAlgError:
        cov = np.full((jac.shape[1],) * 2, np.inf)
    std = np.zeros(n_intrinsic)
    std[free] = np.sqrt(np.abs(np.diag(cov)[:int(free.sum())]))
    count = LENS_MODELS[model].count
    return std[:4 + count], float(std[4 + count]) if model == "omnidir" else 0.0


def _per_view_rms(model: str, points, corners, K, dist, xi, poses) -> np.ndarray:
    out = []
    for pts, seen, (rvec, tvec) in zip(points, corners, poses, strict=True):
        error = project(model, pts, rvec, tvec, K, dist, xi) - np.asarray(seen, float).reshape(-1, 2)
        out.append(np.sqrt(np.mean(np.sum(error**2, axis=1))))
    return np.asarray(out)


def _refine(model: str, points, corners, K: np.ndarray, dist: np.ndarray, xi: float,
            poses: list[tuple[np.ndarray, np.ndarray]], free: np.ndarray):
    """Levenberg-Marquardt on every corner's pixel residual over the free intrinsics (``free``: a
    mask over fx, fy, cx, cy, dist..., xi) and all poses, from OpenCV's answer (scipy least_squares
    with the analytic Jacobian of ``_pose_jacobian``). OpenCV's omnidir fit stops short along the
    valley where xi trades with fx and k1 (measured: xi 0.82 for a true 1.2, its RMS above the
    truth's); the polish reaches the minimum."""
    count = LENS_MODELS[model].count
    start = np.r_[K[0, 0], K[1, 1], K[0, 2], K[1, 2], dist, [xi] if model == "omnidir" else []]
    n_free = int(free.sum())

    def unpack(x: np.ndarray):
        v = start.copy()
        v[free] = x[:n_free]
        K_ = np.array([[v[0], 0.0, v[2]], [0.0, v[1], v[3]], [0.0, 0.0, 1.0]])
        xi_ = float(v[4 + count]) if model == "omnidir" else 0.0
        rest = x[n_free:].reshape(-1, 6)
        return K_, v[4:4 + count], xi_, [(r[:3], r[3:]) for r in rest]

    def residuals(x: np.ndarray) -> np.ndarray:
        return _pose_jacobian(model, points, corners, *unpack(x))[0]

    def jacobian(x: np.ndarray) -> np.ndarray:
        _, jac, n_intrinsic = _pose_jacobian(model, points, corners, *unpack(x))
        return _free_columns(jac, n_intrinsic, free)

    x0 = np.r_[start[free], np.concatenate([np.r_[np.ravel(r), np.ravel(t)] for r, t in poses])]
    result = least_squares(residuals, x0, jac=jacobian, method="lm", xtol=1e-12, ftol=1e-12, max_nfev=200)
    if not result.cost <= 0.5 * float(residuals(x0) @ residuals(x0)):
        return K, dist, xi, poses
    return unpack(result.x)


def _fit_wide(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int], model: str,
              terms: tuple[str, ...]) -> Fit:
    """cv2.fisheye.calibrate or cv2.omnidir.calibrate, coefficients outside ``terms`` held at 0; views
    omnidir's initialisation skips get their pose from ``solve_pose`` so that every view has an RMS
    and a place in the Jacobian."""
    obj = [np.asarray(p, np.float64).reshape(-1, 1, 3) for p in points]
    img = [np.asarray(c, np.float64).reshape(-1, 1, 2) for c in corners]
    xi = 0.0
    held = 0
    for name, flag in WIDE_HOLD_FLAGS[model].items():
        held |= 0 if name in terms else flag
    try:
        if model == "fisheye":
            wide_flags = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW | held
            rms, K, D, rvecs, tvecs = cv2.fisheye.calibrate(obj, img, size, np.eye(3), np.zeros(4), flags=wide_flags,
                                                            criteria=FIT_CRITERIA)
            used = list(range(len(obj)))
        else:
            wide_flags = cv2.omnidir.CALIB_FIX_SKEW | held
            rms, K, xi_out, D, rvecs, tvecs, idx = cv2.omnidir.calibrate(
                [o.reshape(1, -1, 3) for o in obj], [i.reshape(1, -1, 2) for i in img], size, np.eye(3),
                np.zeros((1, 1)), np.zeros((1, 4)), wide_flags, FIT_CRITERIA)
            xi = float(np.ravel(xi_out)[0])
            used = [int(i) for i in np.ravel(idx)] if idx is not None else []
    except cv2.error as error:
        raise _calibration_failed(len(points), error) from None
    dist = np.asarray(D, float).ravel()
    K = np.asarray(K, float)
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(dist)) and np.isfinite(xi)) or len(used) < 3:
        raise _calibration_failed(len(points), f"the {model} fit did not converge")
    K[0, 1] = 0.0
    poses: list[tuple[np.ndarray, np.ndarray] | None] = [None] * len(obj)
    for k, i in enumerate(used):
        poses[i] = (np.asarray(rvecs[k], float).ravel(), np.asarray(tvecs[k], float).ravel())
    full = [p if p is not None else solve_pose(model, points[i], corners[i], K, dist, xi)[1:]
            for i, p in enumerate(poses)]
    free = intrinsic_free(model, terms)
    K, dist, xi, full = _refine(model, points, corners, K, dist, xi, full, free)
    per_view = _per_view_rms(model, points, corners, K, dist, xi, full)
    counts = np.array([len(p) for p in points])
    pooled = float(np.sqrt(np.sum(counts * per_view**2) / np.sum(counts)))
    std, xi_std = _standard_deviations(model, points, corners, K, dist, xi, full, free)
    return Fit(pooled, K, dist, std, per_view, model, xi, xi_std, terms)


def _image_directions(fit: Fit, size: tuple[int, int]) -> list[tuple[float, float]]:
    """(azimuth in normalized coordinates, pixel distance from the principal point) of the image's four
    corners and four edge midpoints."""
    w, h = size[0] - 1.0, size[1] - 1.0
    fx, fy, cx, cy = fit.K[0, 0], fit.K[1, 1], fit.K[0, 2], fit.K[1, 2]
    return [(float(np.arctan2((v - cy) / fy, (u - cx) / fx)), float(np.hypot(u - cx, v - cy)))
            for u, v in ((0, 0), (w, 0), (0, h), (w, h), (w / 2, 0), (w / 2, h), (0, h / 2), (w, h / 2))]


def fold_reason(fit: Fit, size: tuple[int, int]) -> str | None:
    """Why ``fit``'s projection is not physical, or None: a lens maps the angle off its axis to the
    distance from the principal point monotonically [Kannala 2006, Sec. 2: r(theta) increasing; Hartley 2004,
    Sec. 7.4: radial distortion as a monotone map of the radius], so the distance must grow with the
    angle until it reaches the image's edge (its corners and edge midpoints), or until FOLD_FIELD_DEG off
    axis (the hemisphere a fisheye's image circle may end at inside the frame). A fit whose projection
    turns back first has no ray through the image beyond the fold, and two rays through the pixels
    before it: its higher terms extrapolate past the board corners (measured: fisheye k1..k4 on the
    Sony HX5V views folds at 32 deg, 360 px out, the image corners lying 386-413 px out)."""
    cap = np.radians(FOLD_FIELD_DEG - (1.0 if fit.model in ("pinhole", "rational") else 0.0))
    theta = np.linspace(1e-3, cap, FOLD_STEPS)
    centre = fit.K[:2, 2]
    for azimuth, reach in _image_directions(fit, size):
        rays = np.stack([np.sin(theta) * np.cos(azimuth), np.sin(theta) * np.sin(azimuth), np.cos(theta)], 1)
        with np.errstate(all="ignore"):
            distance = np.linalg.norm(project(fit.model, rays, np.zeros(3), np.zeros(3), fit.K, fit.dist, fit.xi)
                                      - centre, axis=1)
        bad = ~np.isfinite(distance[1:]) | (np.diff(distance) <= 0)
        if not bad.any():
            continue
        k = int(np.argmax(bad))
        if distance[:k + 1].max() < reach:
            return (f"the {fit.model} projection with {', '.join(fit.terms) or 'no terms'} folds back "
                    f"{np.degrees(theta[k]):.1f} deg off axis, {distance[k]:.0f} px from the principal point, inside "
                    f"the image ({reach:.0f} px out that way): not a physical lens")
    return None


def fit_model(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int], flags: int,
              model: str = "pinhole", terms: Sequence[str] | None = None) -> Fit:
    """One model's fit (module docstring): ``terms`` the coefficients freed (default: those the
    flags leave free, ``allowed_terms``); UserInputError where the views do not determine it."""
    if model not in LENS_MODELS:
        raise UserInputError("unknown lens model", field="--model", expected=f"one of {', '.join(MODEL_CHOICES)}",
                             got=model)
    chosen = _terms_of(model, flags, terms)
    if model in ("pinhole", "rational"):
        return _fit_opencv(points, corners, size, flags, model, chosen)
    return _fit_wide(points, corners, size, model, chosen)


def solve_pose(model: str, points: np.ndarray, corners: np.ndarray, K: np.ndarray, dist: np.ndarray,
               xi: float = 0.0) -> tuple[float, np.ndarray, np.ndarray]:
    """A view's best pose under fixed intrinsics and its RMS reprojection error: (RMS, rvec, tvec).
    The pinhole by cv2.solvePnP (iterative Levenberg-Marquardt on the reprojection error); the
    other models start from solvePnP on the corners' rays (renderer.lens.normalized) and refine
    the pixel residuals by Levenberg-Marquardt (scipy least_squares, the analytic Jacobian)."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    seen = np.asarray(corners, np.float64).reshape(-1, 2)
    if model == "pinhole":
        ok, rvec, tvec = cv2.solvePnP(points, seen, K, dist)
        if not ok:
            return float("inf"), np.zeros(3), np.zeros(3)
    else:
        rays = normalized(model, seen, K, dist, xi)
        good = np.all(np.isfinite(rays), axis=1)
        if good.sum() < 4:
            return float("inf"), np.zeros(3), np.zeros(3)
        ok, rvec, tvec = cv2.solvePnP(points[good], rays[good], np.eye(3), None)
        if not ok:
            return float("inf"), np.zeros(3), np.zeros(3)

        def residuals(x: np.ndarray) -> np.ndarray:
            return (project(model, points, x[:3], x[3:], K, dist, xi) - seen).ravel()

        def jacobian(x: np.ndarray) -> np.ndarray:
            return project_with_jacobian(model, points, x[:3], x[3:], K, dist, xi)[1][:, :6]

        x = least_squares(residuals, np.r_[np.ravel(rvec), np.ravel(tvec)], jac=jacobian, method="lm").x
        rvec, tvec = x[:3], x[3:]
    projected = project(model, points, rvec, tvec, K, dist, xi)
    rms = float(np.sqrt(np.mean(np.sum((projected - seen) ** 2, axis=1))))
    return rms, np.ravel(rvec), np.ravel(tvec)


def held_out_rms(points: np.ndarray, corners: np.ndarray, fit: Fit) -> float:
    """A view's RMS reprojection error under intrinsics fitted without it, at its own best pose."""
    return solve_pose(fit.model, points, corners, fit.K, fit.dist, fit.xi)[0]

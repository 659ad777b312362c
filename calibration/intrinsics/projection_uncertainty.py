"""How well a board calibration pins down where a ray lands: the projection uncertainty map and
the cross-validation diff, after mrcal's practice (mrcal documentation, "Projection
uncertainty", "Projection differences" and the tour's "Cross-validation" [mrcal]; issue 26 item 2).

Covariance. The board fit [Zhang 2000] minimises every used corner's pixel residual over the
intrinsics and every view's pose. Linearised at the optimum [Hartley 2004, Ch. 5], the free
parameters' covariance is sigma^2 (J^T J)^-1, J the Jacobian of every corner's reprojection
over the free intrinsics and all poses (renderer.lens.project_with_jacobian; omnidir's xi by
central differences, as calibration.intrinsics.lens_models does), sigma^2 the residual sum of squares
over the degrees of freedom left. The intrinsics' block of the inverse is their covariance
with the poses marginalised. Parameters the fit holds (OpenCV's flags: k3 by default, p1 and
p2 under --no-tangential, ...; and the coefficients the term choice left out, Camera.terms) have
no variance.

Projection uncertainty. For each node of a grid over the image (every SAMPLE_STEP_PX pixels,
corners and centre on it), the ray through the pixel under the nominal intrinsics is taken
at infinity: a direction in camera axes, so that no pose's translation enters (mrcal's point:
a point at a finite distance moves with the camera's position as well, and its uncertainty
grows at near range; rays at infinity are what a distant scene needs). Its reprojection under
perturbed intrinsics moves by G dtheta (G the analytic d pixel / d intrinsics at that ray), so
its 2 x 2 covariance is G C G^T. The camera frame, though, is only defined through the boards'
poses: a shift of the principal point with an opposite rotation of every pose fits the corners
almost as well, so a large part of the intrinsics' covariance moves every pixel alike and is
undone by the frame. As the cross-validation does (below), the rotation that best takes up
the perturbation over the grid (least squares, in pixels) is removed before the covariance is
taken: G' = (I - H H^+) G, H the grid's d pixel / d camera rotation. The stated std is the
worst direction's, the square root of the larger eigenvalue of G' C G'^T, in pixels (mrcal's
"worst-direction stdev"). The fixed-frame std (no rotation removed) is given beside it; it
bounds the centre, where a rotation takes up any shift and the re-aligned std reads near zero.

Cross-validation. The used views are split into two disjoint halves (even and odd), each
fitted alone with the same model and flags. The ray through each grid pixel under A is
projected under B after removing the best-fit rotation between the two camera frames (least
squares in pixels over the grid, as mrcal's projection diff fits the implied transformation;
at infinity only a rotation is implied). The diff's norm is held against the predicted
sqrt(sigma_A^2 + sigma_B^2), each half's own worst-direction std. One split is one draw of
the noise, and the diff over the map is dominated by one or two parameter directions, so the
ratio of median diff to median predicted spreads as |z| of one Gaussian draw even where the
model is right (measured on a pinhole camera, 16 views, 30 seeds x 7 splits: median 0.63,
|z|'s is 0.67; 5 % over 2; the half fits' std of fx matches their spread over 40 noise
draws, 0.98). So CV_SPLITS splits are made (even/odd, then balanced random halves, seeded)
and the ratio pooled: the RMS of their median diffs over the RMS of their median predicted
(on those 30 seeds: 0.31-1.95, median 0.85, none over 2; with 3 splits one of 30 was; a
pinhole fitted to a 135-degree fisheye's views 3.6-9.7 over 5 seeds, the fisheye itself
0.67-1.25). A pooled ratio over POOR_RATIO says the model is too poor for the data: the
halves differ by more than the noise explains, so the model's own error dominates.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from scipy.optimize import least_squares

from calibration.intrinsics.lens_models import _pose_jacobian, allowed_terms, fit_model, intrinsic_free, solve_pose
from renderer.lens import LENS_MODELS, normalized, project, project_with_jacobian
from workbench.core.errors import UserInputError

SAMPLE_STEP_PX = 16.0   # grid spacing of the maps (at most; corners and centre are nodes)
PNG_SCALE = 1000.0      # a 16-bit map's value per pixel of std (1 = 0.001 px; 65535 = over 65.5 px or no ray)
POOR_RATIO = 2.0        # median diff over this many times the predicted: the model is too poor for the data
MIN_HALF_VIEWS = 3      # views each half needs to determine the intrinsics (intrinsics_fit.MIN_VIEWS)
CV_SPLITS = 5           # splits of the views into halves (module docstring: one split is one draw of the noise)
CV_SEED = 0             # the random splits' seed (the same views give the same record)
XI_STEP = 1e-6          # central-difference step of xi's column (calibration.intrinsics.lens_models.XI_STEP)


@dataclass
class Camera:
    """One lens model's intrinsics (renderer.lens); ``terms``: the coefficients fitted (None: those the
    flags leave free, calibration.intrinsics.lens_models.allowed_terms)."""

    model: str
    K: np.ndarray
    dist: np.ndarray
    xi: float = 0.0
    terms: tuple[str, ...] | None = None

    @property
    def size(self) -> int:
        """Length of the intrinsic vector: fx, fy, cx, cy, dist..., then xi for omnidir."""
        return 4 + LENS_MODELS[self.model].count + (self.model == "omnidir")


def _free_mask(model: str, flags: int, terms: tuple[str, ...] | None = None) -> np.ndarray:
    """Which entries of the intrinsic vector the fit frees: the coefficients ``terms`` (default: those
    the flags leave free), and OpenCV's flags holding the focal length or principal point."""
    free = intrinsic_free(model, allowed_terms(model, flags) if terms is None else terms)
    if model in ("pinhole", "rational"):
        if flags & cv2.CALIB_FIX_FOCAL_LENGTH:
            free[0:2] = False
        if flags & cv2.CALIB_FIX_PRINCIPAL_POINT:
            free[2:4] = False
    return free


def free_parameters(camera: Camera, flags: int) -> np.ndarray:
    """T (full, free): the intrinsic vector's change is T times the free parameters' change.
    CALIB_FIX_ASPECT_RATIO ties fy to fx (one column moving both by fy/fx)."""
    free = _free_mask(camera.model, flags, camera.terms)
    tied = camera.model in ("pinhole", "rational") and bool(flags & cv2.CALIB_FIX_ASPECT_RATIO) and free[0]
    columns = []
    for i in np.flatnonzero(free):
        if tied and i == 1:
            continue
        column = np.zeros(len(free))
        column[i] = 1.0
        if tied and i == 0:
            column[1] = camera.K[1, 1] / camera.K[0, 0]
        columns.append(column)
    return np.stack(columns, 1)


@dataclass
class Covariance:
    """The intrinsics' covariance (fx, fy, cx, cy, dist..., xi), poses marginalised."""

    matrix: np.ndarray
    sigma_px: float          # residual std per corner coordinate
    dof: int                 # corner coordinates minus free parameters

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.matrix), 0.0, None))


def intrinsics_covariance(camera: Camera, points: Sequence[np.ndarray], corners: Sequence[np.ndarray],
                          flags: int) -> Covariance:
    """sigma^2 (J^T J)^-1 over the free intrinsics and every view's pose, its intrinsic block
    (module docstring; [Hartley 2004, Ch. 5]). Each view's pose is its best under the fitted
    intrinsics (calibration.intrinsics.lens_models.solve_pose), which at the joint optimum is the fit's own."""
    poses = [solve_pose(camera.model, p, c, camera.K, camera.dist, camera.xi)[1:] for p, c in zip(points, corners,
                                                                                                   strict=True)]
    residuals, jac, n_intrinsic = _pose_jacobian(camera.model, points, corners, camera.K, camera.dist, camera.xi,
                                                 poses)
    T = free_parameters(camera, flags)
    J = np.hstack([jac[:, :n_intrinsic] @ T, jac[:, n_intrinsic:]])
    dof = len(residuals) - J.shape[1]
    if dof <= 0:
        raise UserInputError(f"{len(residuals)} corner coordinates cannot determine {J.shape[1]} parameters",
                             field="IMAGE", expected="more board views")
    sigma2 = float(residuals @ residuals) / dof
    try:
        inverse = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        inverse = np.linalg.pinv(J.T @ J)
    block = inverse[:T.shape[1], :T.shape[1]] * sigma2
    return Covariance(T @ block @ T.T, float(np.sqrt(sigma2)), dof)


def grid_axes(size: tuple[int, int], step: float = SAMPLE_STEP_PX) -> tuple[np.ndarray, np.ndarray]:
    """Grid nodes along x and y: an odd count per axis from pixel 0 to the last, at most ``step`` apart,
    so that the corners and the centre are nodes."""
    def axis(n_px: int) -> np.ndarray:
        half = int(np.ceil((n_px - 1) / (2 * step)))
        return np.linspace(0.0, n_px - 1.0, 2 * half + 1)
    return axis(size[0]), axis(size[1])


def _grid_pixels(size: tuple[int, int], step: float) -> tuple[np.ndarray, tuple[int, int]]:
    us, vs = grid_axes(size, step)
    u, v = np.meshgrid(us, vs)
    return np.stack([u.ravel(), v.ravel()], 1), (len(vs), len(us))


def rays_through(camera: Camera, pixels: np.ndarray) -> np.ndarray:
    """Directions (N, 3) = (x/z, y/z, 1) of the rays through pixels; NaN where the model has none."""
    xy = normalized(camera.model, pixels, camera.K, camera.dist, camera.xi)
    return np.c_[xy, np.ones(len(xy))]


def ray_jacobians(camera: Camera, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For rays (N, 3) at infinity: d pixel / d intrinsics (N, 2, size) and d pixel / d camera
    rotation (N, 2, 3), both analytic (renderer.lens.project_with_jacobian; xi by central differences)."""
    zero = np.zeros(3)
    count = LENS_MODELS[camera.model].count
    _, jac = project_with_jacobian(camera.model, rays, zero, zero, camera.K, camera.dist, camera.xi)
    G = jac[:, 6:10 + count]
    if camera.model == "omnidir":
        ahead = project(camera.model, rays, zero, zero, camera.K, camera.dist, camera.xi + XI_STEP)
        back = project(camera.model, rays, zero, zero, camera.K, camera.dist, camera.xi - XI_STEP)
        G = np.c_[G, ((ahead - back) / (2 * XI_STEP)).reshape(-1, 1)]
    return G.reshape(len(rays), 2, -1), jac[:, 0:3].reshape(len(rays), 2, 3)


def _worst_direction_std(covariances: np.ndarray) -> np.ndarray:
    """The square root of the larger eigenvalue of each 2 x 2 covariance (N, 2, 2)."""
    a, b, d = covariances[:, 0, 0], covariances[:, 0, 1], covariances[:, 1, 1]
    largest = 0.5 * (a + d) + np.sqrt(0.25 * (a - d) ** 2 + b * b)
    return np.sqrt(np.clip(largest, 0.0, None))


def projection_std(G: np.ndarray, H: np.ndarray, covariance: np.ndarray, remove_rotation: bool) -> np.ndarray:
    """Worst-direction std (N,) of where each ray lands (module docstring). ``G`` (N, 2, P), ``H``
    (N, 2, 3): rays without a projection carry NaN and are left out of the rotation's fit."""
    good = np.all(np.isfinite(G.reshape(len(G), -1)), axis=1) & np.all(np.isfinite(H.reshape(len(H), -1)), axis=1)
    std = np.full(len(G), np.nan)
    if not good.any():
        return std
    Gg, Hg = G[good], H[good]
    if remove_rotation:
        taken_up = np.linalg.lstsq(Hg.reshape(-1, 3), Gg.reshape(-1, G.shape[2]), rcond=None)[0]
        Gg = Gg - Hg @ taken_up
    std[good] = _worst_direction_std(Gg @ covariance @ np.swapaxes(Gg, 1, 2))
    return std


def _summary(values: np.ndarray) -> dict[str, float | None]:
    """Centre, the four corners, the median and the largest of a grid map (nv, nu)."""
    def number(x: float) -> float | None:
        return float(x) if np.isfinite(x) else None
    nv, nu = values.shape
    finite = values[np.isfinite(values)]
    return {"centre": number(values[nv // 2, nu // 2]), "top_left": number(values[0, 0]),
            "top_right": number(values[0, -1]), "bottom_left": number(values[-1, 0]),
            "bottom_right": number(values[-1, -1]), "median": number(np.median(finite)) if finite.size else None,
            "max": number(finite.max()) if finite.size else None}


@dataclass
class UncertaintyMap:
    """Worst-direction std (px) of where a ray at infinity lands, per grid node (nv, nu)."""

    us: np.ndarray
    vs: np.ndarray
    std_px: np.ndarray            # the camera frame re-aligned (the rotation taken up removed)
    fixed_frame_px: np.ndarray    # the camera frame held

    def to_json(self) -> dict[str, Any]:
        return {"statistic": "worst-direction std of where the ray through a pixel lands (sqrt of the larger "
                             "eigenvalue of its 2x2 covariance), px",
                "rays": "at infinity (directions in camera axes): no pose translation enters",
                "frame": "the camera rotation that best takes up each perturbation over the grid removed, as the "
                         "cross-validation removes the rotation between two fits",
                "grid_step_px": float(self.us[1] - self.us[0]), "grid": [len(self.us), len(self.vs)],
                "std_px": _summary(self.std_px), "fixed_frame_std_px": _summary(self.fixed_frame_px),
                "map_px": {"u": self.us.tolist(), "v": self.vs.tolist(),
                           "std": np.round(np.where(np.isfinite(self.std_px), self.std_px, -1.0), 5).tolist(),
                           "note": "the map's grid nodes (rows v, columns u); -1 where no ray"}}


def map_over(map_px: dict, mask: np.ndarray) -> dict[str, float] | None:
    """Median and largest std (px) of a ``map_px`` record (UncertaintyMap.to_json) over the pixels
    of ``mask`` (H, W), bilinear between the grid's nodes; None where the mask is empty."""
    from scipy.interpolate import RegularGridInterpolator  # deferred: start-up time

    rows, cols = np.nonzero(mask)
    if rows.size == 0:
        return None
    std = np.asarray(map_px["std"], float)
    std[std < 0] = np.nan
    sample = RegularGridInterpolator((np.asarray(map_px["v"], float), np.asarray(map_px["u"], float)), std,
                                     bounds_error=False, fill_value=np.nan)
    values = sample(np.stack([rows, cols], axis=1).astype(float))
    values = values[np.isfinite(values)]
    if values.size == 0:
        return None
    return {"median": float(np.median(values)), "max": float(values.max()), "pixels": int(rows.size)}


def uncertainty_map(camera: Camera, covariance: np.ndarray, size: tuple[int, int],
                    step: float = SAMPLE_STEP_PX) -> UncertaintyMap:
    """The projection uncertainty map of ``camera`` under ``covariance`` (module docstring)."""
    pixels, shape = _grid_pixels(size, step)
    G, H = ray_jacobians(camera, rays_through(camera, pixels))
    us, vs = grid_axes(size, step)
    return UncertaintyMap(us, vs, projection_std(G, H, covariance, True).reshape(shape),
                          projection_std(G, H, covariance, False).reshape(shape))


def fit_rotation(camera_b: Camera, rays_a: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Rotation vector R minimising sum |project_B(R ray_A) - pixel|^2 over the rays with a
    projection (Levenberg-Marquardt, scipy least_squares, the analytic d pixel / d rotation)."""
    good = np.all(np.isfinite(rays_a), axis=1)
    rays, target = rays_a[good], pixels[good]
    zero = np.zeros(3)

    def residuals(r: np.ndarray) -> np.ndarray:
        return (project(camera_b.model, rays, r, zero, camera_b.K, camera_b.dist, camera_b.xi) - target).ravel()

    def jacobian(r: np.ndarray) -> np.ndarray:
        return project_with_jacobian(camera_b.model, rays, r, zero, camera_b.K, camera_b.dist, camera_b.xi)[1][:, :3]

    return least_squares(residuals, np.zeros(3), jac=jacobian, method="lm").x


def _stats(values: np.ndarray) -> dict[str, float]:
    finite = values[np.isfinite(values)]
    return {"median": float(np.median(finite)), "p95": float(np.percentile(finite, 95))}


@dataclass
class SplitDiff:
    """One split's two fits and their projection diff against the predicted spread."""

    diff_px: np.ndarray          # |ray through the pixel under A, projected under B, frames aligned - pixel|
    predicted_px: np.ndarray     # sqrt(sigma_A^2 + sigma_B^2)
    views: tuple[list[int], list[int]]
    rotation_deg: float          # the rotation removed between the two frames
    halves: tuple[Camera, Camera]

    @property
    def ratio(self) -> float:
        """Median diff over median predicted."""
        return _stats(self.diff_px)["median"] / max(_stats(self.predicted_px)["median"], 1e-12)


@dataclass
class CrossValidation:
    """The splits' diffs (the first: even and odd views) and their pooled ratio."""

    us: np.ndarray
    vs: np.ndarray
    splits: list[SplitDiff]

    @property
    def ratio(self) -> float:
        """RMS over the splits of the median diff, over that of the median predicted (module docstring)."""
        diff = [_stats(s.diff_px)["median"] for s in self.splits]
        predicted = [_stats(s.predicted_px)["median"] for s in self.splits]
        return float(np.sqrt(np.mean(np.square(diff))) / max(np.sqrt(np.mean(np.square(predicted))), 1e-12))

    @property
    def too_poor(self) -> bool:
        return self.ratio > POOR_RATIO

    def to_json(self) -> dict[str, Any]:
        first = self.splits[0]
        diff, predicted = _stats(first.diff_px), _stats(first.predicted_px)

        def grid(values: np.ndarray) -> list:
            return np.round(np.where(np.isfinite(values), values, -1.0), 5).tolist()
        return {"halves": "even and odd used views, each fitted alone", "views": [len(v) for v in first.views],
                "diff": "the ray through a pixel under A projected under B, the best-fit rotation between the "
                        "frames removed (rays at infinity), px", "rotation_removed_deg": first.rotation_deg,
                "predicted": "sqrt(sigma_A^2 + sigma_B^2), each half's worst-direction std, px",
                "diff_px": diff, "predicted_px": predicted,
                "ratio": {"median": first.ratio, "p95": diff["p95"] / max(predicted["p95"], 1e-12)},
                "splits": {"count": len(self.splits), "ratios": [s.ratio for s in self.splits],
                           "pooled_ratio": self.ratio,
                           "how": "the first split is even/odd; the others balanced random halves (seeded); the "
                                  "pooled ratio is the RMS of the splits' median diffs over that of their medians "
                                  "predicted"},
                "too_poor": self.too_poor, "poor_ratio": POOR_RATIO,
                "map_px": {"u": self.us.tolist(), "v": self.vs.tolist(), "diff": grid(first.diff_px),
                           "predicted": grid(first.predicted_px),
                           "note": "the first split's maps at the grid nodes (rows v, columns u); -1 where no ray"},
                **({"verdict": f"the halves differ by {self.ratio:.1f} x what the noise explains: the model is too "
                               "poor for the data"} if self.too_poor else {})}


def partitions(count: int, splits: int = CV_SPLITS) -> list[tuple[list[int], list[int]]]:
    """Disjoint halves of ``count`` views: even/odd, then ``splits - 1`` balanced random ones (seeded)."""
    out = [(list(range(0, count, 2)), list(range(1, count, 2)))]
    rng = np.random.default_rng(CV_SEED)
    for _ in range(splits - 1):
        order = rng.permutation(count)
        out.append((sorted(int(i) for i in order[:count // 2]), sorted(int(i) for i in order[count // 2:])))
    return out


def _half(model: str, points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int],
          flags: int, terms: tuple[str, ...] | None) -> tuple[Camera, np.ndarray]:
    fit = fit_model(points, corners, size, flags, model, terms)
    half = Camera(fit.model, fit.K, fit.dist, fit.xi, fit.terms)
    return half, intrinsics_covariance(half, points, corners, flags).matrix


def split_diff(model: str, points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int],
               flags: int, views: tuple[list[int], list[int]], step: float = SAMPLE_STEP_PX,
               terms: tuple[str, ...] | None = None) -> SplitDiff:
    """One split's diff map and predicted map (module docstring), each half fitting ``terms``."""
    (a, cov_a), (b, cov_b) = (_half(model, [points[i] for i in h], [corners[i] for i in h], size, flags, terms)
                              for h in views)
    pixels, shape = _grid_pixels(size, step)
    rays_a = rays_through(a, pixels)
    rotation = fit_rotation(b, rays_a, pixels)
    landed = project(b.model, np.where(np.isfinite(rays_a), rays_a, 0.0), rotation, np.zeros(3), b.K, b.dist, b.xi)
    diff = np.linalg.norm(landed - pixels, axis=1)
    diff[~np.all(np.isfinite(rays_a), axis=1)] = np.nan
    sigmas = [uncertainty_map(c, cov, size, step).std_px for c, cov in ((a, cov_a), (b, cov_b))]
    return SplitDiff(diff.reshape(shape), np.hypot(*sigmas), views, float(np.degrees(np.linalg.norm(rotation))),
                     (a, b))


def cross_validate(model: str, points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int],
                   flags: int, step: float = SAMPLE_STEP_PX, splits: int = CV_SPLITS,
                   terms: tuple[str, ...] | None = None) -> CrossValidation:
    """The cross-validation diff (module docstring) of ``model`` fitting ``terms`` on the views given;
    UserInputError when either half has fewer than MIN_HALF_VIEWS views or cannot be fitted."""
    if len(points) < 2 * MIN_HALF_VIEWS:
        raise UserInputError(f"a cross-validation needs {2 * MIN_HALF_VIEWS} views (two halves of "
                             f"{MIN_HALF_VIEWS}), got {len(points)}", field="IMAGE")
    us, vs = grid_axes(size, step)
    return CrossValidation(us, vs, [split_diff(model, points, corners, size, flags, views, step, terms)
                                    for views in partitions(len(points), splits)])


@dataclass
class ProjectionUncertainty:
    """What calibration.intrinsics.calibrate records: the covariance's map, and the cross-validation (or why not)."""

    covariance: Covariance
    map: UncertaintyMap
    cross_validation: CrossValidation | None
    cross_validation_note: str = ""
    seconds: float = 0.0
    warnings: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"projection_uncertainty": {**self.map.to_json(), "residual_sigma_px": self.covariance.sigma_px,
                                           "dof": self.covariance.dof, "seconds": self.seconds},
                "cross_validation": (self.cross_validation.to_json() if self.cross_validation is not None
                                     else {"skipped": self.cross_validation_note})}


def assess(camera: Camera, points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int],
           flags: int, step: float = SAMPLE_STEP_PX) -> ProjectionUncertainty:
    """The projection uncertainty map of a calibration fitted to these views, and its
    cross-validation diff where the views make two halves (module docstring)."""
    start = time.perf_counter()
    covariance = intrinsics_covariance(camera, points, corners, flags)
    result = ProjectionUncertainty(covariance, uncertainty_map(camera, covariance.matrix, size, step), None)
    try:
        result.cross_validation = cross_validate(camera.model, points, corners, size, flags, step,
                                                 terms=camera.terms)
    except UserInputError as error:
        result.cross_validation_note = error.reason
    if result.cross_validation is not None and result.cross_validation.too_poor:
        result.warnings.append(f"cross-validation: two halves of the views differ by {result.cross_validation.ratio:.1f}"
                               f" x their predicted uncertainty: the {camera.model} model is too poor for the data")
    result.seconds = time.perf_counter() - start
    return result


def write_map_png(path: str | Path, values_px: np.ndarray) -> None:
    """A grid map (px) as a 16-bit grey PNG: value = px * PNG_SCALE, 65535 where over range or no ray."""
    scaled = np.where(np.isfinite(values_px), np.round(values_px * PNG_SCALE), 65535.0)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), np.clip(scaled, 0, 65535).astype(np.uint16)):
        raise OSError(f"could not write {path}")

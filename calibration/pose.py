"""Pose and field of view of a scene photograph (``workbench calibrate pose``).

The scene file's camera is the starting guess; the scene's known 3D edges
(calibration.scene_model: the Cornell box's creases and open front, the ceiling light's
rectangle, each CD's rim) are projected with the camera model (renderer.camera, OpenCV's
pinhole with radial-tangential distortion) and aligned with the photo's edges in three
stages:

1. **Coarse** (nlopt, BOBYQA: M. J. D. Powell, "The BOBYQA algorithm for bound
   constrained optimization without derivatives", Cambridge NA Report 2009/06): the
   truncated chamfer cost of the projected edge points against the photo's Canny edges
   (calibration.edges.ChamferMap), coarse to fine over image scales, so that a start tens
   of pixels off still lands in the right basin. Unknowns: the 6 pose parameters, and,
   without intrinsics, the focal length and the principal point.
2. **Fine**: sub-pixel edge positions along each projected edge's normal
   (calibration.edges.edge_offsets), then robust (Huber) least squares of the
   point-to-edge distances over the same unknowns (+ k1 without intrinsics), with the
   analytic Jacobian of cv2.projectPoints; repeated with shrinking search windows until
   the projection stops moving (the "moving edges" scheme of C. Harris, "Tracking with
   rigid models", Active Vision 1992, and T. Drummond and R. Cipolla, IEEE TPAMI 24(7),
   2002, eqs. 3-6). With intrinsics given they are held fixed.
3. **Render check** (renderer.fit.FitRenderer: the scene rendered with the fitted camera,
   fixed seed): the photometric scale (exposure x light power) is the ratio of the photo
   to the render over the walls, and the render, scaled, clipped, mosaicked and
   demosaicked like the photo, is measured by the same edge finder at the same points:
   what it finds there is the finder's own bias (shading across a crease, blur, clipping
   at the light), which is subtracted from the photo's offsets before a last fine fit
   (analysis by synthesis).
4. **CD fringes** (calibration.photometric, ``PoseSettings.cd_fringes``): with the walls'
   scale known, the photo's CD against re-renders cropped to the disc, over the camera's
   rotation (nlopt BOBYQA, fixed seed). A check by default: its suggested rotation and
   residuals go to the outputs; ``cd_fringes_apply`` takes the step only within a guard
   (see that module for why it is not applied: measured, it does not beat the edges).

Uncertainties: the covariance of the fine fit, s^2 (J^T W J)^-1, with W the Huber weights
and s^2 their weighted residual variance (Gauss-Newton approximation of the cost's
curvature), plus what a systematic offset, tilt or bow of each edge (the edge finder's
residual bias, >= 0.02 px) and the uncertainty of intrinsics held fixed do to the
solution (first-order propagation), plus, with intrinsics free, the spread of restarts.
Residuals are reported in pixels, per feature. Measured on the draft synthetic dataset
(tests/calibration/test_pose.py): with board intrinsics, 0.055-0.06 deg and 0.25-0.3 mm,
most of it the board's principal point (1 px off in cy); with the true intrinsics,
0.008-0.013 deg and 0.04-0.2 mm. Without intrinsics one photo of the box leaves the
principal point, tilt and focal length weakly determined (0.3-0.5 deg, 3-6 mm, 0.1-0.2 deg
of FOV), which ``std`` says.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration.edges import ChamferMap, edge_offsets, smoothed
from calibration.photo import Photo, mosaic_like, read_photo
from calibration.photometric import FringeSettings, refine_rotation
from calibration.scene_model import FeatureSamples, SceneModel, sample_features, scene_model
from renderer.camera import CameraModel
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text
from workbench.core.version import versions as installed_versions

POSE_FORMAT = "workbench-calibrate-pose"
MIN_EDGE_POINTS = 40          # fewer measured edge points than this: the photo does not show the scene
BLACK_LEVEL_FRACTION = 1e-3   # a photo whose 99th percentile is below this (of the white level) is black
SATURATED_SHARE = 0.98        # a photo with more saturated pixels than this share is white
RESTART_SHIFT = 0.01          # with intrinsics free, restarts move the principal point by 1 % of the image
FREE_RADIAL_TERMS = 1         # without intrinsics: k1 only (k2 trades with the focal length and principal point)
RESCALE_AFTER_PX = 0.5       # the render check's last refit moved the camera more: the scale is measured again there
HUBER_PX = 0.5                # residuals beyond this (pixels) count linearly: hidden or foreign edges


@dataclass(frozen=True)
class PoseSettings:
    coarse_levels: tuple[tuple[float, float], ...] = ((0.25, 12.0), (0.5, 8.0), (1.0, 4.0))  # (image scale, cap px)
    coarse_spacing_px: float = 6.0
    coarse_max_evals: int = 800
    coarse_starts: int = 6            # seeded random starts per level besides the previous level's answer
    coarse_start_spread: float = 0.25  # their range, as a share of the level's bound on each unknown
    fine_windows_px: tuple[float, ...] = (6.0, 4.0, 3.0, 2.5)
    fine_spacing_px: float = 2.0
    fine_rounds: int = 4
    min_contrast: float = 3.0     # an edge's steepest slope over the image's slope noise (edges.derivative_noise)
    occluder_margin_px: float = 6.0
    render_check: bool = True
    render_spp: int = 16
    render_seed: int = 0
    cd_fringes: bool = True          # the CD-fringe stage (calibration.photometric), after the render check
    cd_fringes_apply: bool = False   # take its rotation step (guarded) instead of only reporting it
    fringes: FringeSettings = dataclasses.field(default_factory=FringeSettings)

    def to_json(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(self).items()}


@dataclass(frozen=True)
class Unknowns:
    """The fitted parameters: the pose (rotation vector, translation of world_to_camera),
    and optionally the focal length (fx and fy together, their ratio kept: square pixels
    when the start has them), the principal
    point, and the first ``radial`` radial distortion terms (k1; k1, k2)."""

    intrinsics: bool
    radial: int = 0

    @property
    def names(self) -> tuple[str, ...]:
        return (("rx", "ry", "rz", "tx", "ty", "tz") + (("f", "cx", "cy") if self.intrinsics else ())
                + ("k1", "k2")[: self.radial])

    def vector(self, camera: CameraModel) -> np.ndarray:
        rvec, _ = cv2.Rodrigues(camera.world_to_camera[:3, :3])
        x = list(rvec.ravel()) + list(camera.world_to_camera[:3, 3])
        if self.intrinsics:
            x += [camera.fx, camera.cx, camera.cy]
        x += list(camera.dist[: self.radial])
        return np.asarray(x, float)

    def camera(self, x: np.ndarray, template: CameraModel) -> CameraModel:
        T = np.eye(4)
        T[:3, :3] = cv2.Rodrigues(np.asarray(x[:3], float))[0]
        T[:3, 3] = x[3:6]
        changes: dict = {"world_to_camera": T}
        i = 6
        if self.intrinsics:
            aspect = template.fy / template.fx
            changes |= {"fx": float(x[i]), "fy": float(x[i] * aspect), "cx": float(x[i + 1]), "cy": float(x[i + 2])}
            i += 3
        if self.radial:
            changes["dist"] = tuple(float(v) for v in x[i:i + self.radial]) + tuple(template.dist[self.radial:])
        return dataclasses.replace(template, **changes)

    def steps(self, camera: CameraModel) -> np.ndarray:
        """A typical size of each unknown's uncertainty at the start (for scaling)."""
        s = [math.radians(1.0)] * 3 + [0.01] * 3
        if self.intrinsics:
            s += [0.02 * camera.fx, 0.01 * camera.width, 0.01 * camera.height]
        s += [0.02, 0.01][: self.radial]
        return np.asarray(s)

    def columns(self, jac: np.ndarray, camera: CameraModel) -> np.ndarray:
        """cv2.projectPoints' Jacobian (2N, 10 + 5) restricted to these unknowns."""
        cols = [jac[:, :6]]
        if self.intrinsics:
            cols += [(jac[:, 6] + jac[:, 7] * camera.fy / camera.fx)[:, None], jac[:, 8:10]]
        cols.append(jac[:, 10:10 + self.radial])
        return np.concatenate(cols, axis=1)


def project(camera: CameraModel, points: np.ndarray, with_jacobian: bool = False):
    rvec, _ = cv2.Rodrigues(camera.world_to_camera[:3, :3])
    pixels, jac = cv2.projectPoints(np.asarray(points, float).reshape(-1, 1, 3), rvec, camera.world_to_camera[:3, 3],
                                    camera.K, camera.dist_array)
    return (pixels.reshape(-1, 2), jac) if with_jacobian else pixels.reshape(-1, 2)


def image_normals(camera: CameraModel, samples: FeatureSamples, pixels: np.ndarray) -> np.ndarray:
    """Unit normals (N, 2) of the projected features at their sample points."""
    ahead = project(camera, samples.points + 1e-3 * samples.tangents)
    d = ahead - pixels
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    return np.stack([-d[:, 1], d[:, 0]], 1)


# ------------------------------------------------------------------------------------------- coarse


def coarse_fit(photo_grey: np.ndarray, model: SceneModel, start: CameraModel, unknowns: Unknowns,
               settings: PoseSettings) -> tuple[CameraModel, list[dict]]:
    """Stage 1: minimise the capped chamfer cost with nlopt (BOBYQA), level by level.

    The capped cost has several basins: from one start, BOBYQA fell into a wrong one
    (3 px RMS at full scale instead of 0.7 px) on 8 of 12 starts that differed by 1e-9 in
    the focal length. Each level therefore also starts from ``coarse_starts`` seeded
    random points around the previous answer, and polishes each answer once more from a
    smaller step; the lowest cost wins (0 of 30 such starts failed)."""
    coarse = Unknowns(unknowns.intrinsics, 0)
    camera = start
    log = []
    rng = np.random.default_rng(0)
    for scale, cap in settings.coarse_levels:
        chamfer = ChamferMap.from_image(photo_grey, scale, cap)
        samples = sample_features(model, camera, settings.coarse_spacing_px, margin_px=2.0,
                                  occluder_margin_px=settings.occluder_margin_px)
        if len(samples.points) < MIN_EDGE_POINTS:
            break
        x0, steps = coarse.vector(camera), coarse.steps(camera)
        template = camera

        def cost(z, _grad, samples=samples, chamfer=chamfer, x0=x0, steps=steps, template=template) -> float:
            pixels = project(coarse.camera(x0 + z * steps, template), samples.points)
            return float(np.mean(chamfer.cost(pixels)))

        bound = 6.0 / scale ** 0.5
        starts = [np.zeros(len(x0))] + [rng.uniform(-1.0, 1.0, len(x0)) * settings.coarse_start_spread * bound
                                        for _ in range(settings.coarse_starts)]
        best_z, best_value, evaluations = starts[0], math.inf, 0
        for z in starts:
            for step in (0.5, 0.25):  # a second run from the answer: BOBYQA's model may have stalled
                z, value, count = _bobyqa(cost, z, bound, step, settings.coarse_max_evals)
                evaluations += count
            if value < best_value:
                best_z, best_value = z, value
        camera = coarse.camera(x0 + best_z * steps, template)
        log.append({"scale": scale, "cap_px": cap, "points": int(len(samples.points)), "starts": len(starts),
                    "evaluations": evaluations, "rms_before_px": math.sqrt(cost(np.zeros(len(x0)), None)),
                    "rms_after_px": math.sqrt(best_value)})
    return camera, log


def _bobyqa(cost, z0: np.ndarray, bound: float, step: float, max_evals: int) -> tuple[np.ndarray, float, int]:
    """One nlopt BOBYQA run of ``cost`` from ``z0`` within +-``bound``: (answer, cost there, evaluations)."""
    import nlopt

    opt = nlopt.opt(nlopt.LN_BOBYQA, len(z0))
    opt.set_min_objective(cost)
    opt.set_lower_bounds(-bound * np.ones(len(z0)))
    opt.set_upper_bounds(bound * np.ones(len(z0)))
    opt.set_initial_step(step * np.ones(len(z0)))
    opt.set_xtol_abs(1e-3)
    opt.set_maxeval(max_evals)
    z = opt.optimize(np.clip(z0, -bound, bound))
    return z, float(opt.last_optimum_value()), int(opt.get_numevals())


# --------------------------------------------------------------------------------------------- fine


@dataclass
class EdgeMatch:
    """Measured edge points at one camera: where each projected sample's edge was found."""

    samples: FeatureSamples
    pixels: np.ndarray     # (N, 2) predicted
    normals: np.ndarray    # (N, 2)
    offsets: np.ndarray    # (N,) measured, pixels along the normal
    sign: np.ndarray       # (N,) the polarity of the edge (+1: brighter along the normal)
    valid: np.ndarray | None = None  # (N,) where an edge was found (None: everywhere)

    @property
    def targets(self) -> np.ndarray:
        return self.pixels + self.offsets[:, None] * self.normals


def match_edges(image: np.ndarray, model: SceneModel, camera: CameraModel, window: float, settings: PoseSettings,
                samples: FeatureSamples | None = None, sign: np.ndarray | None = None, keep_all: bool = False) -> EdgeMatch:
    """Sample the features at ``camera`` (or use ``samples``) and find each one's edge in
    ``image``; only the points where an edge was found, or with ``keep_all`` every point
    (``valid`` says which were found)."""
    if samples is None:
        samples = sample_features(model, camera, settings.fine_spacing_px, margin_px=window + 3,
                                  occluder_margin_px=max(settings.occluder_margin_px, window))
    pixels = project(camera, samples.points)
    normals = image_normals(camera, samples, pixels)
    found = edge_offsets(image, pixels, normals, window, sign)
    keep = found.valid & (found.contrast >= settings.min_contrast)
    if keep_all:
        return EdgeMatch(samples, pixels, normals, found.offset, found.polarity, keep)
    return EdgeMatch(samples.subset(keep), pixels[keep], normals[keep], found.offset[keep], found.polarity[keep])


def _residuals(x: np.ndarray, unknowns: Unknowns, template: CameraModel, match: EdgeMatch) -> np.ndarray:
    pixels = project(unknowns.camera(x, template), match.samples.points)
    return np.einsum("ij,ij->i", pixels - match.targets, match.normals)


def _jacobian(x: np.ndarray, unknowns: Unknowns, template: CameraModel, match: EdgeMatch) -> np.ndarray:
    camera = unknowns.camera(x, template)
    _, jac = project(camera, match.samples.points, with_jacobian=True)
    J = unknowns.columns(jac, camera).reshape(-1, 2, len(x))
    return np.einsum("ikj,ik->ij", J, match.normals)


def solve_match(match: EdgeMatch, unknowns: Unknowns, camera: CameraModel) -> tuple[CameraModel, dict]:
    """Robust least squares of the point-to-edge distances (Huber, HUBER_PX)."""
    from scipy.optimize import least_squares

    x0 = unknowns.vector(camera)
    result = least_squares(_residuals, x0, jac=_jacobian, args=(unknowns, camera, match), loss="huber",
                           f_scale=HUBER_PX, x_scale=unknowns.steps(camera), method="trf", max_nfev=50)
    fitted = unknowns.camera(result.x, camera)
    return fitted, {"x": result.x, "residuals": result.fun, "jacobian": result.jac}


def image_shift_px(a: CameraModel, b: CameraModel, points: np.ndarray) -> float:
    """The largest distance between where two cameras put the same points."""
    return float(np.max(np.linalg.norm(project(a, points) - project(b, points), axis=1)))


def fine_fit(image: np.ndarray, model: SceneModel, start: CameraModel, unknowns: Unknowns,
             settings: PoseSettings) -> tuple[CameraModel, EdgeMatch, list[dict]]:
    """Stage 2: measure edges, solve, repeat with shrinking windows until the projection
    moves less than 0.01 px."""
    camera, log = start, []
    match = None
    for window in settings.fine_windows_px:
        for _ in range(settings.fine_rounds):
            match = match_edges(image, model, camera, window, settings)
            if len(match.offsets) < MIN_EDGE_POINTS:
                raise UserInputError(f"only {len(match.offsets)} edge points of the scene were found in the photo",
                                     expected=f"at least {MIN_EDGE_POINTS}: a photo of the scene, roughly from the scene "
                                              "file's camera")
            fitted, info = solve_match(match, unknowns, camera)
            moved = image_shift_px(camera, fitted, match.samples.points)
            camera = fitted
            log.append({"window_px": window, "points": int(len(match.offsets)), "moved_px": moved,
                        "rms_px": float(np.sqrt(np.mean(np.minimum(info["residuals"] ** 2, 9.0))))})
            if moved < 0.01:
                break
    if match is None:
        raise ValueError("PoseSettings.fine_windows_px and fine_rounds must not be empty")
    return camera, match, log


def bias_corrected_fit(image: np.ndarray, model: SceneModel, start: CameraModel, unknowns: Unknowns,
                       settings: PoseSettings, checked: EdgeMatch, bias: np.ndarray) -> tuple[CameraModel, EdgeMatch, list[dict]]:
    """Stage 3's last fine solves: the photo's edges measured again at ``checked``'s points,
    each offset corrected by the edge finder's ``bias`` there (measured on the render),
    repeated until the projection moves less than 0.01 px."""
    window = settings.fine_windows_px[-1]
    camera, log = start, []
    corrected = checked
    for _ in range(max(settings.fine_rounds, 1)):
        measured = match_edges(image, model, camera, window, settings, samples=checked.samples, sign=checked.sign,
                               keep_all=True)
        usable = np.asarray(measured.valid) & np.isfinite(bias)
        corrected = _subset(dataclasses.replace(measured, offsets=measured.offsets - np.nan_to_num(bias)), usable)
        fitted, _ = solve_match(corrected, unknowns, camera)
        moved = image_shift_px(camera, fitted, corrected.samples.points)
        camera = fitted
        log.append({"window_px": window, "points": int(len(corrected.offsets)), "moved_px": moved, "bias_corrected": True})
        if moved < 0.01:
            break
    return camera, corrected, log


# ------------------------------------------------------------------------------------ render check


def photometric_mask(photo: Photo, render_grey: np.ndarray, model: SceneModel, camera: CameraModel) -> np.ndarray:
    """Pixels where photo and render are compared: the walls, at least 6 px from the scene's
    edges, 8 px from the glass, the CDs and the light, away from saturated pixels, and not
    dark in the render."""
    from calibration.scene_model import occluder_mask

    edges = np.zeros(render_grey.shape, np.uint8)
    samples = sample_features(model, camera, 1.0, end_clearance_px=0.0)
    for x, y in np.rint(project(camera, samples.points)).astype(int):
        cv2.circle(edges, (int(x), int(y)), 6, 255, -1)
    blocked = occluder_mask(model, camera, margin_px=8.0)
    saturated = cv2.dilate(photo.saturated.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
    level = np.percentile(render_grey, 99)
    return (edges == 0) & ~blocked & ~saturated & (render_grey > 0.03 * level)


@dataclass
class RenderCheck:
    scale: float            # photo / render over the walls (exposure x light power, relative to the scene file)
    scale_std: float        # the spread of the ratio over 16 blocks of the image (not divided by 4: the path
                            # tracer's heavy-tailed noise makes the mean's error larger than independence suggests)
    bias: np.ndarray        # (N,) the edge finder's offset on the render at the match's points
    pixels_compared: int
    seconds: float


def render_check(renderer, photo: Photo, model: SceneModel, camera: CameraModel, match: EdgeMatch, window: float,
                 settings: PoseSettings) -> RenderCheck:
    """Render at ``camera``, find the photometric scale, and measure the edge finder's bias on the render."""
    tick = time.perf_counter()
    renderer.set(camera=camera)
    render = np.asarray(renderer.render(seed=settings.render_seed), np.float32)
    grey = render.mean(axis=2)
    mask = photometric_mask(photo, grey, model, camera)
    if mask.sum() < 1000:
        raise UserInputError("the photo and the scene's render share too few unsaturated wall pixels to compare",
                             file=photo.path, expected="a photo of the scene that is not mostly saturated")
    photo_grey = photo.grey
    scale = float(photo_grey[mask].sum() / grey[mask].sum())
    blocks = [float(photo_grey[mask & part].sum() / max(grey[mask & part].sum(), 1e-30))
              for part in _blocks(mask.shape, 4) if (mask & part).sum() > 50]
    scale_std = float(np.std(blocks, ddof=1)) if len(blocks) > 1 else float("nan")
    like_photo = np.clip(mosaic_like(np.clip(render * scale, 0.0, None), photo.cfa), 0.0, 1.0)  # clipped at white
    found = edge_offsets(smoothed(like_photo.mean(axis=2)), match.pixels, match.normals, window, sign=match.sign)
    bias = np.where(found.valid, found.offset, np.nan)
    return RenderCheck(scale, scale_std, bias, int(mask.sum()), time.perf_counter() - tick)


def _blocks(shape: tuple[int, int], n: int) -> list[np.ndarray]:
    h, w = shape
    rows, cols = np.mgrid[0:h, 0:w]
    return [((rows * n // h) == i) & ((cols * n // w) == j) for i in range(n) for j in range(n)]


# ----------------------------------------------------------------------------------- uncertainty


FEATURE_BIAS_FLOOR_PX = 0.02  # the edge finder's systematic error per feature is at least this (0.034 px at worst on exact steps)


def _feature_bias_covariance(match: EdgeMatch, r: np.ndarray, J: np.ndarray, w: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """What a systematic error per feature does to the solution: every feature's residuals
    may be off by an unknown offset and an unknown tilt along it (shading across a crease,
    clipping, a mis-modelled object), of standard deviation sigma_b (the RMS of the
    features' median residuals, at least FEATURE_BIAS_FLOOR_PX). Each such error moves the
    solution by (J^T W J)^-1 J^T W b; their covariances add. Random pixel noise alone (the
    s^2 term) averages down over thousands of points; these do not, and where a single
    photo constrains some unknowns weakly (free intrinsics) they dominate."""
    features = match.samples.feature
    names = np.unique(features)
    medians = np.array([np.median(r[features == f]) for f in names])
    sigma_b = max(float(np.sqrt(np.mean(medians**2))), FEATURE_BIAS_FLOOR_PX)
    cov = np.zeros((J.shape[1], J.shape[1]))
    for f in names:
        mask = features == f
        tangent = np.stack([-match.normals[mask, 1], match.normals[mask, 0]], 1)
        along = np.einsum("ij,ij->i", match.pixels[mask] - match.pixels[mask].mean(0), tangent)
        span = max(float(np.max(np.abs(along))), 1e-9)
        for pattern in (np.ones(mask.sum()), along / span, 2 * (along / span) ** 2 - 1):
            g = normal @ (J[mask].T @ (w[mask] * pattern))
            cov += sigma_b**2 * np.outer(g, g)
    return cov


FIXED_INTRINSICS = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")  # cv2.projectPoints' columns 6..14


def covariance(match: EdgeMatch, unknowns: Unknowns, camera: CameraModel,
               fixed_std: dict | None = None) -> tuple[np.ndarray, dict]:
    """s^2 (J^T W J)^-1 at ``camera`` with Huber weights W, and the residual statistics (px).

    With intrinsics held fixed, ``fixed_std`` (their standard deviations: fx, fy, cx, cy,
    dist) adds what their uncertainty does to the fitted unknowns: G C_K G^T, with
    G = -(J^T W J)^-1 J^T W J_K the first-order change of the solution with them
    (the implicit function theorem applied to the normal equations)."""
    x = unknowns.vector(camera)
    r = _residuals(x, unknowns, camera, match)
    J = _jacobian(x, unknowns, camera, match)
    w = np.minimum(1.0, HUBER_PX / np.maximum(np.abs(r), 1e-12))
    dof = max(len(r) - len(x), 1)
    s2 = float(np.sum(w * r**2) / dof)
    normal = np.linalg.pinv(J.T @ (w[:, None] * J))
    cov = s2 * normal + _feature_bias_covariance(match, r, J, w, normal)
    if fixed_std is not None and not unknowns.intrinsics:
        _, jac = project(camera, match.samples.points, with_jacobian=True)
        J_K = np.einsum("ikj,ik->ij", jac[:, 6:15].reshape(-1, 2, 9), match.normals)
        sigma = np.array([fixed_std.get("fx", 0.0), fixed_std.get("fy", 0.0), fixed_std.get("cx", 0.0),
                          fixed_std.get("cy", 0.0), *(list(fixed_std.get("dist", [])) + [0.0] * 5)[:5]], float)
        G = -normal @ J.T @ (w[:, None] * J_K)
        cov = cov + G @ np.diag(np.nan_to_num(sigma) ** 2) @ G.T
    stats = {"points": int(len(r)), "rms_px": float(np.sqrt(np.mean(r**2))), "median_abs_px": float(np.median(np.abs(r))),
             "robust_sigma_px": math.sqrt(s2), "inlier_share": float(np.mean(np.abs(r) <= 3 * HUBER_PX))}
    return cov, stats


def per_feature_residuals(match: EdgeMatch, unknowns: Unknowns, camera: CameraModel) -> dict:
    r = _residuals(unknowns.vector(camera), unknowns, camera, match)
    names = np.asarray(match.samples.names)[match.samples.feature]
    return {str(n): {"points": int((names == n).sum()), "median_px": float(np.median(r[names == n])),
                     "rms_px": float(np.sqrt(np.mean(r[names == n] ** 2)))} for n in sorted(set(names))}


def readout(camera: CameraModel, reference: CameraModel) -> np.ndarray:
    """What a user reads of ``camera``: its rotation relative to ``reference`` (small-angle
    vector, degrees), centre (m), fx, fy, cx, cy, the two FOVs (degrees) and dist."""
    R, t = camera.world_to_camera[:3, :3], camera.world_to_camera[:3, 3]
    dR = R @ reference.world_to_camera[:3, :3].T
    small = 0.5 * np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
    return np.concatenate([np.degrees(small), -R.T @ t, [camera.fx, camera.fy, camera.cx, camera.cy, fov_x_deg(camera),
                                                         fov_y_deg(camera)], camera.dist_array])


def derived_std(camera: CameraModel, unknowns: Unknowns, cov: np.ndarray, fixed_std: dict | None = None,
                repeats: list[CameraModel] | None = None) -> dict:
    """Standard deviations of what a user reads (rotation in degrees, camera centre in metres,
    FOV in degrees, the intrinsics) by first-order propagation of ``cov``; with ``repeats``
    (solutions from other starts), their spread about ``camera`` is added in quadrature."""
    x0 = unknowns.vector(camera)
    steps = unknowns.steps(camera) * 1e-4
    base = readout(camera, camera)
    D = np.stack([(readout(unknowns.camera(x0 + steps[i] * np.eye(len(x0))[i], camera), camera) - base) / steps[i]
                  for i in range(len(x0))], 1)
    variance = np.maximum(np.diag(D @ cov @ D.T), 0.0)
    if repeats:
        spread = np.stack([readout(c, camera) - base for c in repeats])
        variance = variance + np.mean(spread**2, axis=0)
    std = np.sqrt(variance)
    if fixed_std is not None and not unknowns.intrinsics:  # held fixed: their own uncertainty, as given
        std[6:10] = [fixed_std.get(k, float("nan")) for k in ("fx", "fy", "cx", "cy")]
        std[10] = std[6] * abs(_dfov(camera.width, camera.fx))
        std[11] = std[7] * abs(_dfov(camera.height, camera.fy))
        std[12:17] = (list(fixed_std.get("dist", [])) + [float("nan")] * 5)[:5]
    return {"rotation_deg": std[0:3].tolist(), "rotation_total_deg": float(np.linalg.norm(std[0:3])),
            "camera_center_m": std[3:6].tolist(), "fx": float(std[6]), "fy": float(std[7]), "cx": float(std[8]),
            "cy": float(std[9]), "fov_x_deg": float(std[10]), "fov_y_deg": float(std[11]), "dist": std[12:17].tolist()}


def _dfov(size: int, focal: float) -> float:
    """d(FOV in degrees) / d(focal in pixels) for an image side of ``size`` pixels."""
    return -math.degrees(2 * (size / 2) / (focal**2 + (size / 2) ** 2))


def fov_x_deg(camera: CameraModel) -> float:
    return 2 * math.degrees(math.atan(camera.width / (2 * camera.fx)))


def fov_y_deg(camera: CameraModel) -> float:
    return 2 * math.degrees(math.atan(camera.height / (2 * camera.fy)))


# ------------------------------------------------------------------------------------- one photo


@dataclass
class PoseResult:
    photo: str
    camera: CameraModel
    unknowns: Unknowns
    std: dict
    residuals: dict
    exposure_scale: float | None
    exposure_scale_std: float | None
    exposure_time_s: float | None
    log: dict
    timings: dict

    def camera_json(self) -> dict:
        c = self.camera
        return {"width": c.width, "height": c.height, "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy,
                "dist": [float(d) for d in c.dist], "world_to_camera": c.world_to_camera.tolist(),
                "fov_x_deg": fov_x_deg(c), "fov_y_deg": fov_y_deg(c),
                "camera_center_m": (-c.world_to_camera[:3, :3].T @ c.world_to_camera[:3, 3]).tolist()}


def check_photo(photo: Photo) -> None:
    """A photo that is black or saturated all over shows no scene: say so, naming the file."""
    top = float(np.percentile(photo.grey, 99.0))
    if top < BLACK_LEVEL_FRACTION:
        raise UserInputError("the photo is black (its 99th percentile is at the black level)", file=photo.path,
                             expected="an exposed photo of the scene", got=f"99th percentile {top:.2e} of the white level")
    share = float(photo.saturated.mean())
    if share > SATURATED_SHARE:
        raise UserInputError(f"the photo is saturated almost everywhere ({100 * share:.1f} % of pixels)", file=photo.path,
                             expected="an exposed photo of the scene, mostly below the white level")


def fit_photo(photo: Photo, model: SceneModel, start: CameraModel, unknowns: Unknowns, settings: PoseSettings,
              renderer=None, bar=None, intrinsics_std: dict | None = None) -> PoseResult:
    """Coarse, fine, and (with ``renderer``, a renderer.fit.FitRenderer of the scene at the
    photo's resolution) the render check and a last fine solve; see the module docstring.
    ``intrinsics_std``: the standard deviations of intrinsics held fixed (intrinsics.json's
    ``std``), carried into the pose's."""
    check_photo(photo)
    if (photo.width, photo.height) != (start.width, start.height):
        raise UserInputError("the photo's size differs from the camera's", file=photo.path,
                             expected=f"{start.width} x {start.height} pixels", got=f"{photo.width} x {photo.height}")
    timings: dict[str, float] = {}
    tick = time.perf_counter()
    camera, coarse_log = coarse_fit(photo.grey, model, start, unknowns, settings)
    timings["coarse_s"] = time.perf_counter() - tick
    _advance(bar)
    tick = time.perf_counter()
    image = smoothed(photo.grey)
    camera, match, fine_log = fine_fit(image, model, camera, unknowns, settings)
    timings["fine_s"] = time.perf_counter() - tick
    _advance(bar)
    scale = scale_std = None
    check_log: dict = {}
    if renderer is not None:
        window = settings.fine_windows_px[-1]
        match = match_edges(image, model, camera, window, settings)
        check = render_check(renderer, photo, model, camera, match, window, settings)
        usable = np.isfinite(check.bias) & (np.abs(check.bias) < window)
        before, checked = camera, _subset(match, usable)
        camera, match, refit_log = bias_corrected_fit(image, model, camera, unknowns, settings, checked, check.bias[usable])
        moved = image_shift_px(before, camera, checked.samples.points)
        if moved > RESCALE_AFTER_PX:  # the walls' mask was drawn at a camera this far off: measure the scale again
            check = dataclasses.replace(render_check(renderer, photo, model, camera, match, window, settings), bias=check.bias)
        scale, scale_std = check.scale, check.scale_std
        names = np.asarray(checked.samples.names)[checked.samples.feature]
        check_log = {"seconds": check.seconds, "pixels_compared": check.pixels_compared, "points": int(usable.sum()),
                     "moved_px": moved, "scale_measured_again": moved > RESCALE_AFTER_PX, "refit": refit_log,
                     "bias_median_px": {str(n): float(np.median(check.bias[usable][names == n])) for n in sorted(set(names))}}
        timings["render_check_s"] = time.perf_counter() - tick - timings["fine_s"]
    _advance(bar)
    repeats = restarts(image, model, camera, unknowns, settings) if unknowns.intrinsics else None
    cov, stats = covariance(match, unknowns, camera, intrinsics_std)
    residuals = stats | {"per_feature": per_feature_residuals(match, unknowns, camera)}
    std = derived_std(camera, unknowns, cov, intrinsics_std, repeats)
    fringes = None
    if renderer is not None and scale is not None and settings.cd_fringes:
        tick = time.perf_counter()
        fringes = refine_rotation(renderer, photo, model, camera, scale, np.asarray(std["rotation_deg"]), settings.fringes,
                                  settings.cd_fringes_apply)
        if fringes is not None and fringes.accepted:
            camera = fringes.camera
            residuals = covariance(match, unknowns, camera, intrinsics_std)[1] | {
                "per_feature": per_feature_residuals(match, unknowns, camera)}
        timings["cd_fringes_s"] = time.perf_counter() - tick
    fringe_log = (fringes.to_json() | {"spp": settings.render_spp} if fringes is not None else
                  {"accepted": False, "reason": "off" if not settings.cd_fringes or renderer is None else "too few CD pixels"})
    return PoseResult(photo.path, camera, unknowns, std, residuals, scale, scale_std, photo.exposure_time_s,
                      {"coarse": coarse_log, "fine": fine_log, "render_check": check_log, "cd_fringes": fringe_log}, timings)


def restarts(image: np.ndarray, model: SceneModel, camera: CameraModel, unknowns: Unknowns,
             settings: PoseSettings) -> list[CameraModel]:
    """The fine fit again from the solution with its principal point moved by
    RESTART_SHIFT of the image each way: with intrinsics free, one photo of the box leaves
    a long, shallow valley (principal point, tilt, focal length and distance trade
    against each other at the level of the edge finder's systematic error, ~0.05 px), and
    where a fit ends in it depends on where it starts; the spread of these ends is the
    uncertainty the curvature alone understates."""
    ends = []
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        start = dataclasses.replace(camera, cx=camera.cx + dx * RESTART_SHIFT * camera.width,
                                    cy=camera.cy + dy * RESTART_SHIFT * camera.height)
        try:
            end, _, _ = fine_fit(image, model, start, unknowns, settings)
        except UserInputError:  # lost the edges from this start: no spread to learn from it
            continue
        ends.append(end)
    return ends


def _subset(match: EdgeMatch, keep: np.ndarray) -> EdgeMatch:
    return EdgeMatch(match.samples.subset(keep), match.pixels[keep], match.normals[keep], match.offsets[keep],
                     match.sign[keep])


def _advance(bar) -> None:
    if bar is not None:
        bar.update()


# ------------------------------------------------------------------------------------- files in, out


def load_intrinsics(path: str | Path) -> dict:
    """intrinsics.json (``workbench calibrate intrinsics``): width, height, fx, fy, cx, cy,
    dist [k1, k2, p1, p2, k3] and, when present, ``std``."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise UserInputError(f"cannot be read ({exc})", file=path, expected="intrinsics.json") from None
    except ValueError as exc:
        raise UserInputError(f"is not JSON ({exc})", file=path, expected="intrinsics.json") from None
    if not isinstance(data, dict):
        raise UserInputError("is not an intrinsics file", file=path, expected="a JSON object")
    for key in ("width", "height", "fx", "fy", "cx", "cy", "dist"):
        if key not in data:
            raise UserInputError("is missing", file=path, field=key, expected="what `workbench calibrate intrinsics` writes")
    dist = data["dist"]
    if not isinstance(dist, list) or len(dist) not in (4, 5) or not all(isinstance(d, (int, float)) for d in dist):
        raise UserInputError("must be 4 or 5 numbers", file=path, field="dist", expected="[k1, k2, p1, p2, k3]", got=dist)
    for key in ("fx", "fy", "width", "height"):
        if not isinstance(data[key], (int, float)) or not data[key] > 0:
            raise UserInputError("must be a positive number", file=path, field=key, got=data[key])
    return {"width": int(data["width"]), "height": int(data["height"]), "fx": float(data["fx"]), "fy": float(data["fy"]),
            "cx": float(data["cx"]), "cy": float(data["cy"]), "dist": tuple(float(d) for d in (list(dist) + [0.0])[:5]),
            "std": data.get("std") if isinstance(data.get("std"), dict) else None, "source": str(path)}


def load_inverse_response(path: str | Path):
    """response.json's (or truth.json's form) ``points``, pairs of normalised irradiance and
    value, as the inverse: value -> irradiance (piecewise linear, monotone)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
        points = np.asarray(data["points"] if "points" in data else data["response"]["points"], float)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise UserInputError(f"holds no response curve ({type(exc).__name__})", file=path,
                             expected="response.json with points [[irradiance, value], ...]") from None
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 2 or np.any(np.diff(points[:, 1]) <= 0):
        raise UserInputError("the response's points must be pairs with increasing values", file=path, field="points")
    return lambda values: np.interp(values, points[:, 1], points[:, 0]).astype(np.float32)


def start_camera(spec, photo: Photo, intrinsics: dict | None) -> CameraModel:
    """The scene's camera at the photo's resolution, with the given intrinsics when there are
    (else with square pixels)."""
    from renderer.render import with_resolution

    if intrinsics is not None and (intrinsics["width"], intrinsics["height"]) != (photo.width, photo.height):
        raise UserInputError("the photo's size differs from the intrinsics'", file=photo.path,
                             expected=f"{intrinsics['width']} x {intrinsics['height']} pixels as in {intrinsics['source']}",
                             got=f"{photo.width} x {photo.height}")
    camera = with_resolution(spec, (photo.width, photo.height)).camera.model
    if intrinsics is not None:
        return dataclasses.replace(camera, fx=intrinsics["fx"], fy=intrinsics["fy"], cx=intrinsics["cx"],
                                   cy=intrinsics["cy"], dist=intrinsics["dist"])
    # To be fitted: square pixels (fy = fx; the fit keeps the ratio), which a resolution's
    # rounding in the scene file (326 x 245 for 25 x 18.8 mm) would otherwise bend by 0.4 %.
    focal = math.sqrt(camera.fx * camera.fy)
    return dataclasses.replace(camera, fx=focal, fy=focal)


def fit_renderer(spec, camera: CameraModel, spp: int):
    """renderer.fit.FitRenderer of ``spec`` seen by ``camera`` (its resolution and intrinsics)."""
    from renderer.fit import FitRenderer

    seen = dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, model=camera))
    return FitRenderer(seen, resolution=(camera.width, camera.height), spp=spp)


def versions() -> dict[str, str]:
    """Versions of what a pose fit depends on (recorded in every output)."""
    return installed_versions("numpy", "scipy", "opencv", "nlopt", "mitsuba")


def result_json(result: PoseResult) -> dict:
    return {"photo": result.photo, "camera": result.camera_json(), "fitted": list(result.unknowns.names),
            "std": result.std, "exposure_scale": result.exposure_scale, "exposure_scale_std": result.exposure_scale_std,
            "exposure_time_s": result.exposure_time_s, "residuals": result.residuals, "stages": result.log,
            "timings": result.timings}


def calibrate_pose(photo_path: str | Path, scene: str | Path, out: str | Path | None = None, *,
                   intrinsics: str | Path | None = None, response: str | Path | None = None,
                   settings: PoseSettings | None = None, progress: bool = True) -> dict:
    """``workbench calibrate pose``: fit one photo; write OUT/pose.json and OUT/fitted_scene.toml.

    Without ``intrinsics`` the focal length (fx, fy with the scene's ratio), the principal
    point and k1, k2 are fitted too; a single photo of the box constrains them weakly (see
    ``std``). ``response`` linearises a non-raw photo. Returns pose.json's content."""
    from tqdm import tqdm

    from renderer.scene import load_scene

    started = time.perf_counter()
    settings = settings or PoseSettings()
    spec = load_scene(scene)
    known = load_intrinsics(intrinsics) if intrinsics is not None else None
    inverse = load_inverse_response(response) if response is not None else None
    photo = read_photo(photo_path, inverse)
    check_photo(photo)
    start = start_camera(spec, photo, known)
    unknowns = Unknowns(intrinsics=known is None, radial=FREE_RADIAL_TERMS if known is None else 0)
    bar = tqdm(total=3, desc="calibrate pose", unit="stage", disable=not progress)
    renderer = fit_renderer(spec, start, settings.render_spp) if settings.render_check else None
    result = fit_photo(photo, scene_model(spec), start, unknowns, settings, renderer, bar,
                       known["std"] if known else None)
    bar.close()
    record = {"format": POSE_FORMAT, "command": "workbench calibrate pose", "scene": str(scene),
              "intrinsics": known["source"] if known else None, "response": str(response) if response else None,
              **result_json(result), "light_power_scale": 1.0,
              "photometry": PHOTOMETRY_NOTE, "linear": photo.linear, "settings": settings.to_json(), "versions": versions()}
    record["timings"] = result.timings | {"total_s": time.perf_counter() - started}
    if out is not None:
        write_outputs(Path(out), "pose.json", record, spec, result.camera, result.exposure_scale)
    return record


PHOTOMETRY_NOTE = ("exposure_scale: photo / render of the scene file (linear, 1 = the white level) over the walls; one "
                   "photo's brightness is exposure x light power, so light_power_scale is held at 1 and exposure_scale "
                   "is their product")


def write_outputs(out: Path, name: str, record: dict, spec, camera: CameraModel, scale: float | None) -> None:
    """``name`` (JSON) and fitted_scene.toml in ``out``, each written atomically."""
    from calibration.fitted_scene import fitted_scene_text

    if out.exists() and not out.is_dir():
        raise UserInputError("is a file, not a folder", field="--out", expected="a folder for the results", got=str(out))
    out.mkdir(parents=True, exist_ok=True)
    exposure = spec.camera.exposure * (scale if scale is not None else 1.0)
    note = f"{spec.name} with the camera fitted by workbench calibrate ({name}); exposure: the photometric fit"
    atomic_write_text(out / "fitted_scene.toml", fitted_scene_text(spec, camera, exposure, note))
    atomic_write_text(out / name, json.dumps(record, indent=2, default=_json_default) + "\n")


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")

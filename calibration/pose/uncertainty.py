"""Uncertainties of a pose fit (calibration.pose.calibrate): the covariance of the fine fit, s^2
(J^T W J)^-1 with Huber weights W (Gauss-Newton approximation of the cost's curvature),
plus what a systematic error per edge and the uncertainty of intrinsics held fixed do to
the solution (first-order propagation), and the standard deviations of what a user reads
(rotation, camera centre, field of view, intrinsics).
"""

from __future__ import annotations

import math

import numpy as np

from calibration.pose.edge_fit import HUBER_PX, EdgeMatch, Unknowns, edge_jacobian, edge_residuals, project
from renderer.camera import CameraModel

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


POSE_READOUTS = ("rotation_x_deg", "rotation_y_deg", "rotation_z_deg", "center_x_m", "center_y_m", "center_z_m",
                 "fx", "fy", "cx", "cy")  # readout's first ten: derived_std's ``covariance``
FIXED_INTRINSICS = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")  # cv2.projectPoints' columns 6..14


def covariance(match: EdgeMatch, unknowns: Unknowns, camera: CameraModel,
               fixed_std: dict | None = None) -> tuple[np.ndarray, dict]:
    """s^2 (J^T W J)^-1 at ``camera`` with Huber weights W, and the residual statistics (px)
    (covariance_parts without the cross term)."""
    cov, stats, _ = covariance_parts(match, unknowns, camera, fixed_std)
    return cov, stats


def covariance_parts(match: EdgeMatch, unknowns: Unknowns, camera: CameraModel,
                     fixed_std: dict | None = None) -> tuple[np.ndarray, dict, np.ndarray | None]:
    """s^2 (J^T W J)^-1 at ``camera`` with Huber weights W, the residual statistics (px), and
    the fitted unknowns' covariance with the held intrinsics (None when they are fitted).

    With intrinsics held fixed, ``fixed_std`` (their standard deviations: fx, fy, cx, cy,
    dist) adds what their uncertainty does to the fitted unknowns: G C_K G^T, with
    G = -(J^T W J)^-1 J^T W J_K the first-order change of the solution with them
    (the implicit function theorem applied to the normal equations); their covariance with
    the unknowns is G C_K (unknowns x fx, fy, cx, cy)."""
    x = unknowns.vector(camera)
    r = edge_residuals(x, unknowns, camera, match)
    J = edge_jacobian(x, unknowns, camera, match)
    w = np.minimum(1.0, HUBER_PX / np.maximum(np.abs(r), 1e-12))
    dof = max(len(r) - len(x), 1)
    s2 = float(np.sum(w * r**2) / dof)
    normal = np.linalg.pinv(J.T @ (w[:, None] * J))
    cov = s2 * normal + _feature_bias_covariance(match, r, J, w, normal)
    cross = None
    if fixed_std is not None and not unknowns.intrinsics:
        _, jac = project(camera, match.samples.points, with_jacobian=True)  # rvec, tvec, fx, fy, cx, cy, the model's dist
        count = jac.shape[1] - 6
        J_K = np.einsum("ikj,ik->ij", jac[:, 6:].reshape(-1, 2, count), match.normals)
        sigma = np.array([fixed_std.get("fx", 0.0), fixed_std.get("fy", 0.0), fixed_std.get("cx", 0.0),
                          fixed_std.get("cy", 0.0), *(list(fixed_std.get("dist", [])) + [0.0] * count)[:count - 4]], float)
        G = -normal @ J.T @ (w[:, None] * J_K)
        C_K = np.diag(np.nan_to_num(sigma) ** 2)
        cov = cov + G @ C_K @ G.T
        cross = (G @ C_K)[:, :4]
    stats = {"points": int(len(r)), "rms_px": float(np.sqrt(np.mean(r**2))), "median_abs_px": float(np.median(np.abs(r))),
             "robust_sigma_px": math.sqrt(s2), "inlier_share": float(np.mean(np.abs(r) <= 3 * HUBER_PX))}
    return cov, stats, cross


def per_feature_residuals(match: EdgeMatch, unknowns: Unknowns, camera: CameraModel) -> dict:
    r = edge_residuals(unknowns.vector(camera), unknowns, camera, match)
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
                repeats: list[CameraModel] | None = None, cross: np.ndarray | None = None) -> dict:
    """Standard deviations of what a user reads (rotation in degrees, camera centre in metres,
    FOV in degrees, the intrinsics) by first-order propagation of ``cov``; with ``repeats``
    (solutions from other starts), their spread about ``camera`` is added in quadrature.
    ``covariance``: the joint covariance of the first ten readouts (``POSE_READOUTS``), with
    ``cross`` (covariance_parts: the unknowns with the held intrinsics) where they are held."""
    x0 = unknowns.vector(camera)
    steps = unknowns.steps(camera) * 1e-4
    base = readout(camera, camera)
    D = np.stack([(readout(unknowns.camera(x0 + steps[i] * np.eye(len(x0))[i], camera), camera) - base) / steps[i]
                  for i in range(len(x0))], 1)
    full = D @ cov @ D.T
    if repeats:
        spread = np.stack([readout(c, camera) - base for c in repeats])
        full = full + spread.T @ spread / len(repeats)
    variance = np.maximum(np.diag(full), 0.0)
    std = np.sqrt(variance)
    joint = _readout_covariance(full, D, fixed_std, cross, unknowns)
    if fixed_std is not None and not unknowns.intrinsics:  # held fixed: their own uncertainty, as given
        std[6:10] = [fixed_std.get(k, float("nan")) for k in ("fx", "fy", "cx", "cy")]
        std[10] = std[6] * abs(_dfov(camera.width, camera.fx))
        std[11] = std[7] * abs(_dfov(camera.height, camera.fy))
        count = len(camera.dist)   # the lens model's coefficients (renderer.lens)
        std[12:12 + count] = (list(fixed_std.get("dist", [])) + [float("nan")] * count)[:count]
    return {"rotation_deg": std[0:3].tolist(), "rotation_total_deg": float(np.linalg.norm(std[0:3])),
            "camera_center_m": std[3:6].tolist(), "fx": float(std[6]), "fy": float(std[7]), "cx": float(std[8]),
            "cy": float(std[9]), "fov_x_deg": float(std[10]), "fov_y_deg": float(std[11]), "dist": std[12:].tolist(),
            "covariance": {"parameters": list(POSE_READOUTS), "matrix": joint.tolist()}}


def _readout_covariance(full: np.ndarray, D: np.ndarray, fixed_std: dict | None, cross: np.ndarray | None,
                        unknowns: Unknowns) -> np.ndarray:
    """The joint covariance of the readouts ``POSE_READOUTS``: rotation and centre, which are
    strongly correlated in a pose fit (a small turn and a sideways shift move the scene's
    image alike, so the fit pins their sum far better than either), and the intrinsics.
    Propagating their standard deviations as if independent put the CD's band edges 0.5-2 px
    off (RMS over six draft datasets) where the calibrated cameras put them 0.03-0.14 px off
    the true cameras' edges. Held intrinsics enter with their own variances (``fixed_std``)
    and their covariance with the pose (``cross``, first-order: D G C_K)."""
    joint = full[:10, :10].copy()
    if fixed_std is not None and not unknowns.intrinsics:
        held = np.nan_to_num(np.array([fixed_std.get(k, 0.0) for k in ("fx", "fy", "cx", "cy")], float))
        joint[6:10, 6:10] = np.diag(held**2)
        if cross is not None:
            joint[:6, 6:10] = D[:6] @ cross
            joint[6:10, :6] = joint[:6, 6:10].T
    return joint


def _dfov(size: int, focal: float) -> float:
    """d(FOV in degrees) / d(focal in pixels) for an image side of ``size`` pixels."""
    return -math.degrees(2 * (size / 2) / (focal**2 + (size / 2) ** 2))


def fov_x_deg(camera: CameraModel) -> float:
    return 2 * math.degrees(math.atan(camera.width / (2 * camera.fx)))


def fov_y_deg(camera: CameraModel) -> float:
    return 2 * math.degrees(math.atan(camera.height / (2 * camera.fy)))


"""The lens models a camera may have, shared by calibration and the renderer.

Each model maps a point in camera axes (x right, y down, z forward, OpenCV's) to a pixel
through OpenCV's own function, and back through OpenCV's inverse refined by Newton's method:

* ``pinhole``: the radial-tangential model, coefficients (k1, k2, p1, p2, k3)
  [Zhang 2000; OpenCV calib3d "Camera Calibration and 3D Reconstruction"]
  (cv2.projectPoints, cv2.undistortPoints).
* ``rational``: OpenCV's rational model (CALIB_RATIONAL_MODEL), (k1, k2, p1, p2, k3, k4,
  k5, k6): the radial factor (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
  (same functions, eight coefficients).
* ``fisheye``: Kannala-Brandt [Kannala 2006] as OpenCV's fisheye module has it,
  (k1, k2, k3, k4): theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8),
  the distorted point at theta_d along the ray's azimuth (cv2.fisheye.projectPoints,
  cv2.fisheye.undistortPoints), no skew.
* ``omnidir``: Mei's unified model [Mei 2007] (opencv-contrib's cv2.omnidir):
  the point on the unit sphere is projected from (0, 0, -xi), then the radial-tangential
  distortion (k1, k2, p1, p2); ``xi`` is the model's one extra parameter, no skew.

Rays are given as normalized coordinates (x/z, y/z), so a ray must point forward
(z > 0): the renderer's ideal pinhole intermediate cannot hold more (renderer.camera).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

NEWTON_ITERATIONS = 30        # Newton steps polishing OpenCV's inverse (2-4 are needed; the rest guard the worst pixels)
NEWTON_TOLERANCE_PX = 1e-10   # stop once every pixel is reproduced to this
DIFFERENCE_STEP = 1e-7        # normalized-coordinate step of the Newton Jacobian's central differences
UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)


@dataclass(frozen=True)
class LensModel:
    name: str
    coefficients: tuple[str, ...]   # the names of ``dist``'s entries, in order
    description: str

    @property
    def count(self) -> int:
        return len(self.coefficients)


LENS_MODELS: dict[str, LensModel] = {
    "pinhole": LensModel("pinhole", ("k1", "k2", "p1", "p2", "k3"), "OpenCV's radial-tangential model"),
    "rational": LensModel("rational", ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"), "OpenCV's rational model"),
    "fisheye": LensModel("fisheye", ("k1", "k2", "k3", "k4"), "Kannala-Brandt (OpenCV's fisheye)"),
    "omnidir": LensModel("omnidir", ("k1", "k2", "p1", "p2"), "Mei's unified model (cv2.omnidir), with xi"),
}


def lens_model(name: str) -> LensModel:
    """The registered model ``name`` (ValueError naming the choices otherwise)."""
    try:
        return LENS_MODELS[name]
    except KeyError:
        raise ValueError(f"unknown lens model {name!r}: expected one of {', '.join(LENS_MODELS)}") from None


def check_coefficients(model: str, dist, xi: float) -> tuple[float, ...]:
    """``dist`` as a tuple of floats of the model's length; ValueError otherwise (or on xi for a non-omnidir model)."""
    spec = lens_model(model)
    values = tuple(float(d) for d in dist)
    if len(values) != spec.count:
        raise ValueError(f"the {model} lens model has {spec.count} coefficients ({', '.join(spec.coefficients)}), "
                         f"got {len(values)}")
    if model != "omnidir" and xi != 0.0:
        raise ValueError(f"xi is a parameter of the omnidir model only, not of {model}")
    return values


def project(model: str, points: np.ndarray, rvec: np.ndarray, tvec: np.ndarray, K: np.ndarray, dist: np.ndarray,
            xi: float = 0.0) -> np.ndarray:
    """Pixels (N, 2) of points (N, 3) given in the frame that (rvec, tvec) takes to camera axes."""
    pts = np.ascontiguousarray(np.asarray(points, np.float64).reshape(-1, 1, 3))
    rvec = np.ascontiguousarray(rvec, np.float64).reshape(3, 1)   # contiguous: omnidir misreads a strided view
    tvec = np.ascontiguousarray(tvec, np.float64).reshape(3, 1)
    dist = np.asarray(dist, np.float64)
    if len(pts) == 0:
        return np.zeros((0, 2))
    if model in ("pinhole", "rational"):
        pixels, _ = cv2.projectPoints(pts, rvec, tvec, K, dist)
    elif model == "fisheye":
        pixels, _ = cv2.fisheye.projectPoints(pts, rvec, tvec, K, dist.reshape(4, 1))
    elif model == "omnidir":
        pixels, _ = cv2.omnidir.projectPoints(pts.reshape(1, -1, 3), rvec, tvec, K, float(xi), dist.reshape(1, 4))
    else:
        lens_model(model)
    return np.asarray(pixels, float).reshape(-1, 2)


def project_with_jacobian(model: str, points: np.ndarray, rvec: np.ndarray, tvec: np.ndarray, K: np.ndarray,
                          dist: np.ndarray, xi: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (N, 2) and their Jacobian (2N, 10 + coefficients) in cv2.projectPoints' column
    order for every model: rvec (3), tvec (3), fx, fy, cx, cy, then ``dist`` in its order
    (the fisheye's and omnidir's own Jacobians, their columns reordered; skew and xi left out)."""
    pts = np.ascontiguousarray(np.asarray(points, np.float64).reshape(-1, 1, 3))
    rvec = np.ascontiguousarray(rvec, np.float64).reshape(3, 1)   # contiguous: omnidir misreads a strided view
    tvec = np.ascontiguousarray(tvec, np.float64).reshape(3, 1)
    dist = np.asarray(dist, np.float64)
    if model in ("pinhole", "rational"):
        pixels, jac = cv2.projectPoints(pts, rvec, tvec, K, dist)
        return pixels.reshape(-1, 2), jac
    if model == "fisheye":  # columns: f (2), c (2), k (4), om (3), T (3), alpha
        pixels, jac = cv2.fisheye.projectPoints(pts, rvec, tvec, K, dist.reshape(4, 1))
        order = [8, 9, 10, 11, 12, 13, 0, 1, 2, 3, 4, 5, 6, 7]
    elif model == "omnidir":  # columns: om (3), T (3), fx, fy, s, cx, cy, xi, k1, k2, p1, p2
        pixels, jac = cv2.omnidir.projectPoints(pts.reshape(1, -1, 3), rvec, tvec, K, float(xi), dist.reshape(1, 4))
        order = [0, 1, 2, 3, 4, 5, 6, 7, 9, 10, 12, 13, 14, 15]
    else:
        lens_model(model)
    return np.asarray(pixels, float).reshape(-1, 2), np.asarray(jac, float)[:, order]


def _opencv_inverse(model: str, pixels: np.ndarray, K: np.ndarray, dist: np.ndarray, xi: float) -> np.ndarray:
    """OpenCV's own undistortion of pixels (N, 2) to normalized coordinates (x/z, y/z)."""
    p = np.asarray(pixels, np.float64).reshape(-1, 1, 2)
    if model in ("pinhole", "rational"):
        return cv2.undistortPoints(p, K, dist, criteria=UNDISTORT_CRITERIA).reshape(-1, 2)
    if model == "fisheye":
        return cv2.fisheye.undistortPoints(p, K, dist.reshape(4, 1), criteria=UNDISTORT_CRITERIA).reshape(-1, 2)
    # omnidir: OpenCV 5's undistortPoints (R = identity) gives x/z; OpenCV 4's gave the point
    # re-projected from (0, 0, -xi), lifted here to the unit sphere [Mei 2007], the projection inverted
    # and divided by z. Each pixel keeps whichever reading its projection reproduces.
    m = cv2.omnidir.undistortPoints(p.reshape(1, -1, 2), K, dist.reshape(1, 4), np.array([[float(xi)]]),
                                    np.eye(3)).reshape(-1, 2)
    r2 = np.sum(m**2, axis=1)
    a, b, c = r2 + 1, 2 * xi * r2, r2 * xi**2 - 1
    zs = (-b + np.sqrt(np.maximum(b * b - 4 * a * c, 0.0))) / (2 * a)
    lifted = m * ((zs + xi) / np.where(np.abs(zs) > 1e-12, zs, 1e-12))[:, None]
    zero = np.zeros(3)
    errors = [np.linalg.norm(project(model, np.c_[c_, np.ones(len(c_))], zero, zero, K, dist, xi) - p.reshape(-1, 2),
                             axis=1) for c_ in (m, lifted)]
    return np.where((errors[0] <= errors[1])[:, None], m, lifted)


def normalized(model: str, pixels: np.ndarray, K: np.ndarray, dist: np.ndarray, xi: float = 0.0) -> np.ndarray:
    """Normalized coordinates (N, 2) of the rays through pixels (N, 2): the model inverted.

    The pinhole takes cv2.undistortPoints iterated to convergence (as before the other models
    came). The others start from OpenCV's inverse and take Newton steps on the projection
    (a 2 x 2 Jacobian per pixel from central differences) until each pixel is reproduced to
    NEWTON_TOLERANCE_PX: OpenCV's omnidir inverse stops after a fixed number of fixed-point
    rounds, and the fisheye's leaves ~1e-4 px where the distortion is strong. Pixels whose
    ray the model does not reach (beyond the lens's field) come back as NaN."""
    dist = np.asarray(dist, np.float64)
    pixels = np.asarray(pixels, np.float64).reshape(-1, 2)
    start = _opencv_inverse(model, pixels, K, dist, xi)
    if model == "pinhole" or len(pixels) == 0:
        return start
    n = start.copy()
    zero = np.zeros(3)

    def ahead(xy: np.ndarray) -> np.ndarray:
        return project(model, np.c_[xy, np.ones(len(xy))], zero, zero, K, dist, xi)

    h = DIFFERENCE_STEP
    for _ in range(NEWTON_ITERATIONS):
        error = ahead(n) - pixels
        if np.all(np.abs(error) < NEWTON_TOLERANCE_PX):
            break
        jx = (ahead(n + [h, 0]) - ahead(n - [h, 0])) / (2 * h)
        jy = (ahead(n + [0, h]) - ahead(n - [0, h])) / (2 * h)
        det = jx[:, 0] * jy[:, 1] - jy[:, 0] * jx[:, 1]
        det = np.where(np.abs(det) > 1e-300, det, 1e-300)
        step_x = (jy[:, 1] * error[:, 0] - jy[:, 0] * error[:, 1]) / det
        step_y = (-jx[:, 1] * error[:, 0] + jx[:, 0] * error[:, 1]) / det
        n = n - np.stack([step_x, step_y], 1)
    missed = np.linalg.norm(ahead(n) - pixels, axis=1) > 1e-6
    n[missed] = np.nan
    return n

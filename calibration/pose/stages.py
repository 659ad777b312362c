"""One photo through every stage of calibration.pose.calibrate: coarse, fine, the render check (the
photometric scale, and the edge finder's bias measured on the render and subtracted before
a last fine fit), the restarts that measure the spread with intrinsics free, the
uncertainties, and the CD-fringe check (calibration.pose.fringe_rotation). See calibration.pose.calibrate for
the method and its sources.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from calibration.intrinsics.vignetting import WallTiles
from calibration.pose.edge_fit import (
    PoseSettings,
    Unknowns,
    check_coverage,
    coarse_fit,
    edge_coverage,
    fine_fit,
)
from calibration.pose.edges import smoothed
from calibration.pose.fringe_rotation import FringeResult, refine_rotation
from calibration.pose.photo import Photo
from calibration.pose.render_check import render_check_stage
from calibration.pose.scene_model import SceneModel
from calibration.pose.uncertainty import covariance, covariance_parts, derived_std, fov_x_deg, fov_y_deg, per_feature_residuals
from renderer.camera import CameraModel
from workbench.core.errors import UserInputError

BLACK_LEVEL_FRACTION = 1e-3   # a photo whose 99th percentile is below this (of the white level) is black
SATURATED_SHARE = 0.98        # a photo with more saturated pixels than this share is white
RESTART_SHIFT = 0.01          # with intrinsics free, restarts move the principal point by 1 % of the image


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
    wall_tiles: WallTiles | None = None  # the render check's walls, photo / render in tiles (calibration.intrinsics.vignetting)

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
    """Coarse, fine, and (with ``renderer``, a renderer.rerender.FitRenderer of the scene at the
    photo's resolution) the render check and a last fine solve; see calibration.pose.calibrate.
    ``intrinsics_std``: the standard deviations of intrinsics held fixed (intrinsics.json's
    ``std``), carried into the pose's."""
    with one_blas_thread():
        return _fit_photo(photo, model, start, unknowns, settings, renderer, bar, intrinsics_std)


def one_blas_thread():
    """One BLAS thread while a photo is fitted (threadpoolctl), for its many small dense
    solves (scipy's least squares takes an SVD of a ~1500 x 10 Jacobian per step). With two
    threads each of the SVD's synchronisations waits for both to hold a core: on the 2-core
    machine shared with other work one took 37-62 ms instead of 0.3 ms on one thread, 7 s
    of a 20 s photo with intrinsics free (restarts included); the answers are the same
    (measured: identical fitted cameras). Mitsuba renders on its own thread pool, not BLAS."""
    from threadpoolctl import threadpool_limits  # deferred: start-up time

    return threadpool_limits(limits=1, user_api="blas")


def _fit_photo(photo: Photo, model: SceneModel, start: CameraModel, unknowns: Unknowns, settings: PoseSettings,
               renderer, bar, intrinsics_std: dict | None) -> PoseResult:
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
    coverage = edge_coverage(image, model, camera, settings)
    check_coverage(photo.path, coverage)  # before the render check: a photo of something else renders for nothing
    timings["fine_s"] = time.perf_counter() - tick
    _advance(bar)
    scale = scale_std = tiles = None
    check_log: dict = {}
    if renderer is not None:
        tick = time.perf_counter()
        camera, match, check, check_log = render_check_stage(renderer, photo, image, model, camera, unknowns, settings,
                                                             intrinsics_std)
        scale, scale_std, tiles = check.scale, check.scale_std, check.tiles
        timings["render_check_s"] = time.perf_counter() - tick
    _advance(bar)
    repeats = restarts(image, model, camera, unknowns, settings) if unknowns.intrinsics else None
    cov, stats, cross = covariance_parts(match, unknowns, camera, intrinsics_std)
    residuals = stats | coverage | {"per_feature": per_feature_residuals(match, unknowns, camera)}
    std = derived_std(camera, unknowns, cov, intrinsics_std, repeats, cross)
    fringes = None
    if renderer is not None and scale is not None and settings.cd_fringes:
        tick = time.perf_counter()
        fringes = refine_rotation(renderer, photo, model, camera, scale, np.asarray(std["rotation_deg"]), settings.fringes,
                                  settings.cd_fringes_apply)
        if fringes is not None and fringes.accepted:
            camera = fringes.camera
            residuals = covariance(match, unknowns, camera, intrinsics_std)[1] | coverage | {
                "per_feature": per_feature_residuals(match, unknowns, camera)}
        timings["cd_fringes_s"] = time.perf_counter() - tick
    log = {"coarse": coarse_log, "fine": fine_log, "render_check": check_log,
           "cd_fringes": _fringe_log(fringes, renderer is not None, settings)}
    return PoseResult(photo.path, camera, unknowns, std, residuals, scale, scale_std, photo.exposure_time_s, log, timings,
                      tiles)


def _fringe_log(fringes: FringeResult | None, rendered: bool, settings: PoseSettings) -> dict:
    """Stage 4's entry in the log: its result, or why it did not run."""
    if fringes is not None:
        return fringes.to_json() | {"spp": settings.fringes.spp}  # its crops render at their own spp
    return {"accepted": False, "reason": "off" if not settings.cd_fringes or not rendered else "too few CD pixels"}


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


def _advance(bar) -> None:
    if bar is not None:
        bar.update()

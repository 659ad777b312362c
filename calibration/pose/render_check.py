"""Stage 3 of calibration.pose.calibrate, the render check, rendered in passes until its own noise is
small enough.

The render (renderer.rerender.FitRenderer: the scene seen by the fitted camera) gives two
things: the photometric scale (photo / render over the walls) and the edge finder's bias
(the offsets it finds on the render, scaled, clipped, mosaicked and demosaicked like the
photo, at the fit's points), which is subtracted from the photo's offsets before a last
fine fit (calibration.pose.calibrate's analysis by synthesis). Both carry the path tracer's noise.

Instead of one render at a fixed spp, the render is made in passes of
``PoseSettings.render_pass_spp`` samples, each its own seed, and merged (their mean: a
render of the summed samples). Once there are two or more passes its noise is measured
from the passes themselves (the variance between them, as a progressive renderer does):

* the scale's: the spread of the per-pass scales over the same wall pixels, divided by
  sqrt(passes);
* the pose's: the bias-corrected fit is solved from each half of the passes (biases of
  the two half-merged renders); the two solutions differ by the noise of a half, so the
  merged render's noise is |A - B| / 2 (difference of two independent draws: variance
  2 s_half^2, and s_merged^2 = s_half^2 / 2), for the rotation (degrees, small-angle
  vector) and the camera centre (metres).

Passes are doubled until the scale's noise is below SCALE_NOISE and the pose's below
RENDER_NOISE_SHARE of the pose's stated standard deviation (before the check:
calibration.pose.uncertainty, intrinsics' uncertainty included), or until
``PoseSettings.render_spp`` samples are reached (where the pose's noise is not measured:
it could not change what is rendered). Each half's fit is one solve (the noise's
first-order effect), the merged render's the full bias-corrected fit. With ``render_pass_spp >= render_spp``
the check is one render at ``render_spp`` (the fixed behaviour).

Measured on the seed-0 draft dataset's view0 (board intrinsics; 3 seeds each): the
rotation error against truth.json was 0.052-0.074 deg at 4 spp, 0.051-0.069 at 8,
0.055-0.067 at 16 and 0.059-0.064 at 32 (before the check: 0.078), the camera centre's
0.24-0.36 mm at every spp, the scale's spread over seeds 0.1 % at 4 spp and 0.04 % at 16:
the render's noise is a small part of the pose's error (0.065 +- 0.031 deg over render
realisations of the photo, tests/calibration_bounds.py) and of its stated std (0.056 deg).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import cv2
import numpy as np

from calibration.intrinsics.vignetting import WallTiles, wall_tiles
from calibration.pose.edge_fit import (
    EdgeMatch,
    PoseSettings,
    Unknowns,
    bias_corrected_fit,
    image_shift_px,
    match_edges,
    project,
    subset_match,
)
from calibration.pose.edges import edge_offsets, smoothed
from calibration.pose.photo import Photo, mosaic_like
from calibration.pose.scene_model import SceneModel, occluder_mask, sample_features
from calibration.pose.uncertainty import covariance, derived_std, readout
from renderer.camera import CameraModel, PinholePlan
from workbench.core.errors import UserInputError

RESCALE_AFTER_PX = 0.5        # the render check's last refit moved the camera more: the scale is measured again there
RENDER_NOISE_SHARE = 1 / 3    # passes are added until the render's noise moves the pose by under this share of its
                              # stated std (in quadrature: under 6 % more uncertainty) ...
SCALE_NOISE = 1e-3            # ... and the photometric scale by under 0.1 % (a tenth of issue 14's 1 % bar)


def photometric_mask(photo: Photo, render_grey: np.ndarray, model: SceneModel, camera: CameraModel) -> np.ndarray:
    """Pixels where photo and render are compared: the walls, at least 6 px from the scene's
    edges, 8 px from the glass, the CDs and the light, away from saturated pixels, and not
    dark in the render."""
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
    spp: int = 0            # samples per pixel rendered in all
    noise: dict = dataclasses.field(default_factory=dict)  # the noise measured at each doubling of the passes
    tiles: WallTiles | None = None  # the walls' photo / render tiles of a linear photo (calibration.intrinsics.vignetting)


def render_pass(renderer, spp: int, seed: int) -> np.ndarray:
    """renderer.rerender.FitRenderer.render with ``spp`` samples per pixel instead of the loaded
    scene's (mi.render's ``spp`` override): the same wide pinhole render, warp and exposure."""
    wide = np.array(renderer.mi.render(renderer.scene, renderer.params, seed=seed, spp=spp))
    plan = PinholePlan(renderer.wide_size[0], renderer.wide_size[1], renderer.focal, 0.0, renderer.camera.mitsuba_to_world())
    return renderer.camera.warp(wide, plan) * renderer.exposure


def _scale(photo: Photo, grey: np.ndarray, mask: np.ndarray) -> float:
    return float(photo.grey[mask].sum() / max(float(grey[mask].sum()), 1e-30))


def _bias(render: np.ndarray, scale: float, photo: Photo, match: EdgeMatch, window: float) -> np.ndarray:
    """The edge finder's offsets on ``render`` made like the photo (NaN where it found none)."""
    like_photo = np.clip(mosaic_like(np.clip(render * scale, 0.0, None), photo.cfa), 0.0, 1.0)  # clipped at white
    found = edge_offsets(smoothed(like_photo.mean(axis=2)), match.pixels, match.normals, window, sign=match.sign)
    return np.where(found.valid, found.offset, np.nan)


def _measure(render: np.ndarray, photo: Photo, model: SceneModel, camera: CameraModel, match: EdgeMatch,
             window: float) -> tuple[RenderCheck, np.ndarray]:
    """Scale, its block spread and the bias of one (merged) render; the wall pixels compared."""
    grey = render.mean(axis=2)
    mask = photometric_mask(photo, grey, model, camera)
    if mask.sum() < 1000:
        raise UserInputError("the photo and the scene's render share too few unsaturated wall pixels to compare",
                             file=photo.path, expected="a photo of the scene that is not mostly saturated")
    scale = _scale(photo, grey, mask)
    blocks = [float(photo.grey[mask & part].sum() / max(grey[mask & part].sum(), 1e-30))
              for part in _blocks(mask.shape, 4) if (mask & part).sum() > 50]
    scale_std = float(np.std(blocks, ddof=1)) if len(blocks) > 1 else float("nan")
    return RenderCheck(scale, scale_std, _bias(render, scale, photo, match, window), int(mask.sum()), 0.0), mask


def _tiles(photo: Photo, render: np.ndarray, mask: np.ndarray, camera: CameraModel) -> WallTiles | None:
    """The walls' tiles for the vignetting fit (calibration.intrinsics.vignetting_stage); None for a non-linear photo."""
    return wall_tiles(photo.rgb, render, mask, camera) if photo.linear else None


def render_check(renderer, photo: Photo, model: SceneModel, camera: CameraModel, match: EdgeMatch, window: float,
                 settings: PoseSettings, pose_noise=None) -> RenderCheck:
    """Render at ``camera`` in passes (module docstring), find the photometric scale and the
    edge finder's bias. ``pose_noise(passes, check)``: the pose's noise measured from the
    passes (a dict) and whether it is small enough; without it the passes go on to
    ``render_spp``."""
    tick = time.perf_counter()
    renderer.set(camera=camera)
    per_pass = settings.render_pass_spp
    if per_pass < 1 or settings.render_spp < 1:
        raise ValueError(f"PoseSettings.render_spp and render_pass_spp must be at least 1, not {settings.render_spp} "
                         f"and {per_pass}")
    if 2 * per_pass > settings.render_spp:  # one render at render_spp: nothing to measure the noise with
        render = render_pass(renderer, settings.render_spp, settings.render_seed)
        check, mask = _measure(render, photo, model, camera, match, window)
        return dataclasses.replace(check, seconds=time.perf_counter() - tick, spp=settings.render_spp,
                                   tiles=_tiles(photo, render, mask, camera))
    most = settings.render_spp // per_pass
    passes: list[np.ndarray] = []
    noise: dict = {}
    count = 2
    while True:
        passes += [np.asarray(render_pass(renderer, per_pass, settings.render_seed + k), np.float32)
                   for k in range(len(passes), count)]
        merged = np.mean(passes, axis=0)
        check, mask = _measure(merged, photo, model, camera, match, window)
        scales = [_scale(photo, p.mean(axis=2), mask) for p in passes]
        measured = {"scale_relative": float(np.std(scales, ddof=1) / math.sqrt(len(passes)) / check.scale)}
        enough = measured["scale_relative"] <= SCALE_NOISE
        if pose_noise is not None and count < most:  # at render_spp the answer cannot change what is rendered
            pose, small = pose_noise(passes, check)
            measured |= pose
            enough = enough and small
        noise[str(count * per_pass)] = measured
        if enough or count >= most:
            return dataclasses.replace(check, seconds=time.perf_counter() - tick, spp=count * per_pass, noise=noise,
                                       tiles=_tiles(photo, merged, mask, camera))
        count = min(2 * count, most)


def render_check_stage(renderer, photo: Photo, image: np.ndarray, model: SceneModel, camera: CameraModel,
                       unknowns: Unknowns, settings: PoseSettings,
                       intrinsics_std: dict | None = None) -> tuple[CameraModel, EdgeMatch, RenderCheck, dict]:
    """Stage 3: the render check at ``camera``, the bias-corrected fine solves, and the scale
    measured again if they moved the camera by more than RESCALE_AFTER_PX: (camera, match,
    the check (scale, its spread, the walls' tiles), the stage's log)."""
    window = settings.fine_windows_px[-1]
    match = match_edges(image, model, camera, window, settings)
    stated = derived_std(camera, unknowns, covariance(match, unknowns, camera, intrinsics_std)[0], intrinsics_std)
    bounds = (RENDER_NOISE_SHARE * stated["rotation_total_deg"],
              RENDER_NOISE_SHARE * float(np.linalg.norm(stated["camera_center_m"])))

    def refit(bias: np.ndarray, rounds: int = settings.fine_rounds):
        usable = np.isfinite(bias) & (np.abs(bias) < window)
        checked = subset_match(match, usable)
        once = dataclasses.replace(settings, fine_rounds=rounds)
        return (*bias_corrected_fit(image, model, camera, unknowns, once, checked, bias[usable]), checked, usable)

    def pose_noise(passes: list[np.ndarray], check: RenderCheck) -> tuple[dict, bool]:
        half = len(passes) // 2  # one solve from each half's bias (the noise's first-order effect on the pose)
        a, b = (refit(_bias(np.mean(part, axis=0), check.scale, photo, match, window), 1)[0]
                for part in (passes[:half], passes[half:]))
        d = readout(a, b)
        rotation = float(np.linalg.norm(d[0:3])) / 2
        centre = float(np.linalg.norm(d[3:6] - readout(b, b)[3:6])) / 2
        return ({"rotation_deg": rotation, "centre_m": centre, "rotation_bound_deg": bounds[0], "centre_bound_m": bounds[1]},
                rotation <= bounds[0] and centre <= bounds[1])

    check = render_check(renderer, photo, model, camera, match, window, settings, pose_noise)
    before = camera
    camera, match, refit_log, checked, usable = refit(check.bias)
    moved = image_shift_px(before, camera, checked.samples.points)
    if moved > RESCALE_AFTER_PX:  # the walls' mask was drawn at a camera this far off: measure the scale again
        again = dataclasses.replace(settings, render_spp=check.spp)
        check = dataclasses.replace(render_check(renderer, photo, model, camera, match, window, again), bias=check.bias,
                                    spp=check.spp, noise=check.noise)
    names = np.asarray(checked.samples.names)[checked.samples.feature]
    check_log = {"seconds": check.seconds, "spp": check.spp, "noise": check.noise,
                 "pixels_compared": check.pixels_compared, "points": int(usable.sum()),
                 "moved_px": moved, "scale_measured_again": moved > RESCALE_AFTER_PX, "refit": refit_log,
                 "bias_median_px": {str(n): float(np.median(check.bias[usable][names == n])) for n in sorted(set(names))}}
    return camera, match, check, check_log


def _blocks(shape: tuple[int, int], n: int) -> list[np.ndarray]:
    h, w = shape
    rows, cols = np.mgrid[0:h, 0:w]
    return [((rows * n // h) == i) & ((cols * n // w) == j) for i in range(n) for j in range(n)]

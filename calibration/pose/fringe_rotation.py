"""The CD's fringes as a check (and optional refinement) of a fitted camera's rotation.

Issue 14's last pose stage: once the edge fit (calibration.pose.calibrate) has placed the camera and
the render check has measured the photometric scale on the walls (exposure x light power),
the photo's CD is compared with re-renders of the scene (renderer.rerender.FitRenderer, the same
fixed seed for every render, so that the cost is a smooth function of the camera and not a
new draw of the path tracer's noise each time) as a function of the camera's rotation about
its fitted centre (3 unknowns), minimised with nlopt's BOBYQA
[Powell 2009] from the edge fit.

The fringes are first diffraction orders of the CD's grating: where a pixel sees a
wavelength depends on the direction from the CD to the ceiling light and to the camera
(the grating equation, [Lange 2021, Eq. 2], as renderer.trace.prediction uses it: sin(theta_m) = sin(theta_i) + m lambda /
Lambda), so a fringe moves across the disc as the camera's *centre* moves, but hardly at
all relative to the disc when the camera only turns: a rotation moves the disc and its
fringes together in the image, which the rim's edges already measure to a few hundredths
of a pixel. What the fringes add over the edges is therefore a second, independent
measurement of where the disc is in the image (its bright bands are edges too), weighted
by the bands' contrast and blurred by the render's noise.

Cost (per photo, fixed mask): the photo and the render, the render scaled by the walls'
photometric scale, passed through the photo's colour filter array and demosaicing
(calibration.pose.photo.mosaic_like) and clipped at the white level like the photo, both
blurred by a Gaussian of ``blur_px`` (the render's noise at ``spp``), compared per channel
over the CD's pixels (the top's annulus between the rim and the hub, ``margin_px`` inside
both, unsaturated in the photo), each channel divided by the photo's mean level there;
the cost is the mean Charbonnier penalty sqrt(r^2 + eps^2) - eps of those relative
residuals (smooth, and linear for outliers such as a glass object's caustic).

How it is used (``PoseSettings.cd_fringes_apply``, off by default). Measured on the draft
synthetic datasets of seeds 0, 1, 2 and 5 (two photos each; 16 spp, blur 1 px): the edge
fit's rotation errors against truth.json were 0.065, 0.061, 0.013, 0.014, 0.032, 0.041,
0.083, 0.073 deg; the fringes' step, taken unguarded, made them 0.078, 0.102, 0.049, 0.050,
0.047, 0.036, 0.112, 0.084 deg: worse on seven of eight. The cost at the *true* camera is no lower than at the edge
fit (0.0655 against 0.0604 on seed 0's view0, and within the seed noise elsewhere), so the
fringes cannot see the edge fit's error: a rotation moves the disc and its fringes together
(the fringe colours depend on the directions to the light and to the camera's centre,
which a turn about the centre leaves alone), so this cost measures where the disc lies in
the image, which the rim's edges already measure; the edge fit's remaining error is a
rotation traded against the centre that keeps the image where it is, and its centre part
(< 1 mm at 0.5 m, < 0.1 deg of viewing direction, a few nanometres of fringe wavelength,
a fraction of a pixel across the disc) is below the render noise at 16 spp. Roll about the
optical axis barely changes the cost (the disc is near the image's centre), and BOBYQA's
step there (0.03-0.09 deg) is the noise's. So the stage is a check: calibration.json
records, per photo, ``cd_fringes``: the cost before and after, the rotation it would suggest
(degrees, small-angle vector in the camera's frame, and its size in units of the edge fit's
standard deviation), whether it was accepted and why; a large residual or a large suggested
step on a real photo says the scene model (the CD's place, its grating) or the pose is off.
With ``cd_fringes_apply`` the step is taken only when it lies within GUARD_SIGMA of the edge
fit's rotation uncertainty and the cost falls by more than MIN_FALL and by more than
NOISE_FACTOR times the cost's change with the render seed (its noise floor); on the eight
photos above the guard refused all eight steps (5.6-15.7 sigma, or no clear fall).
Time: 17-21 evaluations of a render cropped to the disc (3-4 % of the wide render's pixels),
7-25 s per photo on this 2-core machine (more when it is loaded); ``calibrate DATASET`` on
the draft dataset took 31 s in all with it (seed 5, 15 s of it the fringes), 46-87 s while
other jobs shared the cores (bar 120 s).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import cv2
import nlopt
import numpy as np

from calibration.pose.photo import Photo, mosaic_like
from calibration.pose.scene_model import Circle, SceneModel
from renderer.camera import CameraModel
from renderer.mitsuba_scene import sensor_dict

GUARD_SIGMA = 3.0       # an accepted step lies within this many of the edge fit's rotation standard deviations
MIN_FALL = 0.02         # and lowers the cost by at least this share ...
NOISE_FACTOR = 3.0      # ... and by this many times the cost's change when only the render seed changes
MIN_CD_PIXELS = 200     # fewer compared CD pixels than this: the photo does not show the disc well enough
CHARBONNIER_EPS = 0.05  # relative residuals below this count quadratically (the render's and photo's noise at 1 px blur)
RIM_POINTS = 180        # points on each projected circle (a 1-degree polygon: < 0.02 px from the ellipse at 640 x 480)
APPLY_NOTE = ("on draft datasets of seeds 0, 1, 2, 5 the fringes' step was further from the truth than the edge fit on "
              "7 of 8 photos (calibration/pose/fringe_rotation.py's docstring), so it is reported and not applied by default")


@dataclass(frozen=True)
class FringeSettings:
    spp: int = 16
    seed: int = 0
    blur_px: float = 1.0
    margin_px: float = 3.0
    max_evals: int = 30
    start_step_deg: float = 0.05
    bound_deg: float = 0.5
    xtol_deg: float = 0.002

    def to_json(self) -> dict:
        return dataclasses.asdict(self)


def rotated(camera: CameraModel, delta_deg: np.ndarray) -> CameraModel:
    """``camera`` turned about its own centre by the small-angle vector ``delta_deg``
    (degrees, in the camera's frame: R' = dR R, the convention of calibration.pose.calibrate.readout)."""
    T = np.array(camera.world_to_camera, float)
    center = -T[:3, :3].T @ T[:3, 3]
    dR = cv2.Rodrigues(np.radians(np.asarray(delta_deg, float)).reshape(3, 1))[0]
    out = np.eye(4)
    out[:3, :3] = dR @ T[:3, :3]
    out[:3, 3] = -out[:3, :3] @ center
    return dataclasses.replace(camera, world_to_camera=out)


def _circle_polygon(camera: CameraModel, center: np.ndarray, normal: np.ndarray, radius: float) -> np.ndarray:
    points, _ = Circle("", center, normal, radius).points(np.linspace(0, 2 * np.pi, RIM_POINTS, endpoint=False))
    return camera.project(points)


def cd_mask(model: SceneModel, camera: CameraModel, margin_px: float) -> np.ndarray:
    """The CDs' tops (bool, H x W): inside each projected rim and outside its hub, ``margin_px``
    in from both (calibration.pose.scene_model's circles and discs; the hub is the disc's inner
    radius on the top face)."""
    mask = np.zeros((camera.height, camera.width), np.uint8)
    for circle in model.circles:
        if not circle.name.startswith("cd["):
            continue
        top = [d for d in model.occluders.discs if np.allclose(d[0], circle.center, atol=1e-9)]
        inner = top[0][2] if top else 0.0
        disc = np.zeros_like(mask)
        outline = _circle_polygon(camera, circle.center, circle.normal, circle.radius)
        cv2.fillPoly(disc, [np.rint(outline * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
        if inner > 0:
            hub = _circle_polygon(camera, circle.center, circle.normal, inner)
            cv2.fillPoly(disc, [np.rint(hub * 16).astype(np.int32)], 0, lineType=cv2.LINE_8, shift=4)
        mask = np.maximum(mask, disc)
    if margin_px > 0:
        size = int(2 * math.ceil(margin_px) + 1)
        return cv2.erode(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))) > 0
    return mask > 0


class CroppedRender:
    """Renders of ``renderer``'s loaded scene (a renderer.rerender.FitRenderer) through a second
    Mitsuba sensor whose film is cropped to the part of the wide pinhole image that covers
    ``region`` (bool, H x W, camera pixels) with ``margin_px`` around it: the same scene, light,
    exposure and pinhole geometry as FitRenderer.render, so the same image there, at a fraction
    of the samples (hdrfilm's crop_offset/crop_size). Only the sensor's pose changes between
    renders (in place, through mi.traverse, so Dr.Jit reuses its kernel); the intrinsics are
    fixed, so the warp's maps (renderer.camera.CameraModel.warp) are computed once."""

    def __init__(self, renderer, camera: CameraModel, region: np.ndarray, margin_px: float, spp: int) -> None:
        self.renderer, self.camera, self.spp = renderer, camera, spp
        mi = renderer.mi
        renderer.set(camera=camera)
        width, height = renderer.wide_size
        focal = renderer.focal
        u, v = np.meshgrid(np.arange(camera.width, dtype=np.float64), np.arange(camera.height, dtype=np.float64))
        normalized = camera.normalized(np.stack([u.ravel(), v.ravel()], 1).reshape(-1, 1, 2))
        self.map_x = (normalized[:, 0] * focal + (width - 1) / 2).reshape(camera.height, camera.width).astype(np.float32)
        self.map_y = (normalized[:, 1] * focal + (height - 1) / 2).reshape(camera.height, camera.width).astype(np.float32)
        xs, ys = self.map_x[region], self.map_y[region]
        x0 = max(int(math.floor(xs.min() - margin_px)), 0)
        y0 = max(int(math.floor(ys.min() - margin_px)), 0)
        x1 = min(int(math.ceil(xs.max() + margin_px)) + 1, width)
        y1 = min(int(math.ceil(ys.max() + margin_px)) + 1, height)
        self.offset, self.size, self.wide = (x0, y0), (x1 - x0, y1 - y0), (width, height)
        sensor, _ = sensor_dict(mi, renderer.spec.camera, spp)  # the scene's own spectral film (camera RGB)
        sensor["fov"] = 2 * math.degrees(math.atan(0.5 * width / focal))
        sensor["to_world"] = mi.ScalarTransform4f(camera.mitsuba_to_world().tolist())
        sensor["film"] |= {"width": width, "height": height, "crop_offset_x": x0, "crop_offset_y": y0,
                           "crop_width": x1 - x0, "crop_height": y1 - y0}
        self.sensor = mi.load_dict(sensor)
        self.params = mi.traverse(self.sensor)

    @property
    def share(self) -> float:
        """The crop's share of the wide render's pixels."""
        return self.size[0] * self.size[1] / (self.wide[0] * self.wide[1])

    def render(self, camera: CameraModel, seed: int) -> np.ndarray:
        """The camera's image (H, W, 3), right inside the region (and its margin), black elsewhere."""
        mi = self.renderer.mi
        self.params["to_world"] = mi.ScalarTransform4f(camera.mitsuba_to_world().tolist())
        self.params.update()
        part = np.array(mi.render(self.renderer.scene, sensor=self.sensor, seed=seed, spp=self.spp))
        wide = np.zeros((self.wide[1], self.wide[0], part.shape[2]), np.float32)
        x0, y0 = self.offset
        wide[y0:y0 + part.shape[0], x0:x0 + part.shape[1]] = part
        image = cv2.remap(wide, self.map_x, self.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return image[..., :3] * self.renderer.exposure


class FringeCost:
    """The CD-fringe cost of a camera (module docstring), with a fixed mask, scale and seed."""

    def __init__(self, renderer, photo: Photo, model: SceneModel, camera: CameraModel, scale: float,
                 settings: FringeSettings) -> None:
        self.renderer, self.photo, self.scale, self.settings = renderer, photo, float(scale), settings
        saturated = cv2.dilate(photo.saturated.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        self.mask = cd_mask(model, camera, settings.margin_px) & ~saturated
        self.pixels = int(self.mask.sum())
        self.target = self._blur(photo.rgb)[self.mask]                       # (N, 3)
        self.level = np.maximum(self.target.mean(axis=0), 1e-6)               # per channel
        self.evaluations = 0
        margin = 3 * settings.blur_px + settings.bound_deg * math.pi / 180 * max(camera.fx, camera.fy) + 4
        self.cropped = CroppedRender(renderer, camera, self.mask, margin, settings.spp) if self.pixels else None

    def _blur(self, rgb: np.ndarray) -> np.ndarray:
        """A 3 x 3 median (the path tracer's fireflies off the CD's specular paths, hot pixels), then the Gaussian."""
        return cv2.GaussianBlur(cv2.medianBlur(np.ascontiguousarray(rgb, np.float32), 3), (0, 0), self.settings.blur_px)

    def render(self, camera: CameraModel, seed: int | None = None) -> np.ndarray:
        """The render at ``camera`` as the photo would show it (scaled, mosaicked, clipped), blurred."""
        assert self.cropped is not None
        render = self.cropped.render(camera, self.settings.seed if seed is None else seed)
        like_photo = np.clip(mosaic_like(np.clip(render * self.scale, 0.0, None), self.photo.cfa), 0.0, 1.0)
        return self._blur(like_photo)

    def __call__(self, camera: CameraModel, seed: int | None = None) -> float:
        self.evaluations += 1
        r = (self.render(camera, seed)[self.mask] - self.target) / self.level
        return float(np.mean(np.sqrt(r**2 + CHARBONNIER_EPS**2) - CHARBONNIER_EPS))


@dataclass
class FringeResult:
    cost_before: float
    cost_after: float
    cost_seed_noise: float
    delta_deg: np.ndarray
    sigma_units: float
    accepted: bool
    reason: str
    pixels: int
    evaluations: int
    seconds: float
    camera: CameraModel   # the refined camera (whether or not it was accepted)

    def to_json(self) -> dict:
        return {"residual_before": self.cost_before, "residual_after": self.cost_after,
                "residual_seed_noise": self.cost_seed_noise,
                "suggested_rotation_delta_deg": [float(v) for v in self.delta_deg],
                "suggested_rotation_deg": float(np.linalg.norm(self.delta_deg)),
                "suggested_in_sigma": self.sigma_units, "accepted": self.accepted, "reason": self.reason,
                "pixels_compared": self.pixels, "evaluations": self.evaluations, "seconds": self.seconds}


def refine_rotation(renderer, photo: Photo, model: SceneModel, camera: CameraModel, scale: float,
                    rotation_std_deg: np.ndarray, settings: FringeSettings, apply: bool) -> FringeResult | None:
    """Minimise the fringe cost over the camera's rotation from ``camera`` (nlopt BOBYQA) and
    decide whether to take the step (module docstring). None when the photo shows too few
    CD pixels to compare."""
    tick = time.perf_counter()
    cost = FringeCost(renderer, photo, model, camera, scale, settings)
    if cost.pixels < MIN_CD_PIXELS:
        return None
    before = cost(camera)
    noise = abs(cost(camera, seed=settings.seed + 1) - before)
    opt = nlopt.opt(nlopt.LN_BOBYQA, 3)
    opt.set_min_objective(lambda x, _grad: cost(rotated(camera, x)))
    opt.set_lower_bounds([-settings.bound_deg] * 3)
    opt.set_upper_bounds([settings.bound_deg] * 3)
    opt.set_initial_step([settings.start_step_deg] * 3)
    opt.set_maxeval(settings.max_evals)
    opt.set_xtol_abs(settings.xtol_deg)
    delta = np.asarray(opt.optimize(np.zeros(3)), float)
    after = float(opt.last_optimum_value())
    sigma = np.maximum(np.asarray(rotation_std_deg, float), 1e-6)
    units = float(np.linalg.norm(delta / sigma))
    fall = before - after
    if not apply:
        accepted, reason = False, "reported only (PoseSettings.cd_fringes_apply is off): " + APPLY_NOTE
    elif units > GUARD_SIGMA:
        accepted, reason = False, f"the step is {units:.1f} sigma of the edge fit's rotation, more than {GUARD_SIGMA:g}"
    elif fall < MIN_FALL * before or fall < NOISE_FACTOR * noise:
        accepted, reason = False, (f"the cost fell by {fall:.3g}, not clearly (needs {MIN_FALL:g} of {before:.3g} "
                                   f"and {NOISE_FACTOR:g} x the seed noise {noise:.3g})")
    else:
        accepted, reason = True, f"the cost fell by {fall:.3g} ({100 * fall / before:.1f} %), step {units:.1f} sigma"
    return FringeResult(before, after, noise, delta, units, accepted, reason, cost.pixels, cost.evaluations,
                        time.perf_counter() - tick, rotated(camera, delta))

"""Fast re-renders for fitting (the ``fit`` preset): one loaded scene, parameters changed in place.

Calibration fits the camera pose, the intrinsics, the exposure and the light power by
re-rendering hundreds of times. Here the Mitsuba scene is built and compiled once;
a change of pose or field of view updates the sensor through ``mi.traverse`` (no
rebuild, and Dr.Jit reuses the compiled kernel), a change of light power scales the
emitter's spectrum in place, and the exposure and the lens distortion only change the
final warp (renderer.camera). ``make bench`` (benchmarks/bench_fit.py)
prints the time per re-render.
"""

from __future__ import annotations

import math

import numpy as np

from renderer.camera import CameraModel, PinholePlan
from renderer.mitsuba_scene import scene_dict
from renderer.render import with_resolution
from renderer.scene import SceneSpec, load_scene
from renderer.variant import set_variant

FIT_RESOLUTION = (160, 120)
FIT_SPP = 16
FOV_MARGIN = 1.15  # the wide render covers intrinsics up to 15 % shorter than the starting focal length


class FitRenderer:
    def __init__(self, scene, resolution: tuple[int, int] = FIT_RESOLUTION, spp: int = FIT_SPP, mode: str = "improved",
                 extra_objects: dict | None = None, integrator: str = "path", max_depth: int = 8) -> None:
        """``scene``: a built-in name, a TOML path, or a parsed renderer.scene.SceneSpec.
        ``extra_objects``: Mitsuba dicts by key, added to the scene (e.g. a calibration
        board); ``move(key, to_world)`` repositions one in place. ``integrator`` and
        ``max_depth``: as renderer.mitsuba_scene.scene_dict (the scene's path tracer by default)."""
        set_variant()
        import mitsuba as mi  # deferred: after set_variant, and start-up time

        self.mi = mi
        spec = scene if isinstance(scene, SceneSpec) else load_scene(scene)
        self.spec = with_resolution(spec, resolution)
        d, built = scene_dict(mi, self.spec, spp=spp, mode=mode, integrator=integrator, max_depth=max_depth)
        plan = built["plan"]
        # A wider pinhole render, so that shorter focal lengths stay covered while fitting.
        self.wide_size = (int(plan.width * FOV_MARGIN) // 2 * 2, int(plan.height * FOV_MARGIN) // 2 * 2)
        d["sensor"]["film"]["width"], d["sensor"]["film"]["height"] = self.wide_size
        for key, obj in (extra_objects or {}).items():
            if key in d:
                raise ValueError(f"extra object {key!r} would replace the scene's own {key!r}")
            d[key] = obj
        self._dict = d
        self.scene = mi.load_dict(d)
        self.params = mi.traverse(self.scene)
        self.base_radiance = np.array(self.params["light.emitter.radiance.values"])
        self.camera = self.spec.camera.model
        self.exposure = self.spec.camera.exposure
        self.light_power_scale = 1.0
        self._apply_camera()

    def set(self, *, camera: CameraModel | None = None, exposure: float | None = None,
            light_power_scale: float | None = None) -> None:
        """Change parameters in place; only what changed is updated."""
        if camera is not None:
            if (camera.width, camera.height) != (self.camera.width, self.camera.height):
                raise ValueError("the fit renderer's resolution is fixed; build another for a new size")
            self.camera = camera
            self._apply_camera()
        if exposure is not None:
            self.exposure = float(exposure)
        if light_power_scale is not None:
            self.light_power_scale = float(light_power_scale)
            self.params["light.emitter.radiance.values"] = self.mi.Float(self.base_radiance * self.light_power_scale)
            self.params.update()

    def move(self, key: str, to_world: np.ndarray) -> None:
        """Place shape ``key`` (an extra object or a scene shape) at ``to_world`` (4 x 4), in place."""
        self.params[f"{key}.to_world"] = self.mi.ScalarTransform4f(np.asarray(to_world, dtype=float).tolist())
        self.params.update()

    def _apply_camera(self) -> None:
        self.focal = max(self.camera.fx, self.camera.fy)
        need = self.camera.pinhole_plan()  # the pinhole image this camera needs, at its own focal length
        if need.width > self.wide_size[0] or need.height > self.wide_size[1]:
            self._grow(need.width, need.height)  # an off-centre or strongly distorted camera (issue 45, item 2)
        self.params["sensor.x_fov"] = 2 * math.degrees(math.atan(0.5 * self.wide_size[0] / self.focal))
        self.params["sensor.to_world"] = self.mi.ScalarTransform4f(self.camera.mitsuba_to_world().tolist())
        self.params.update()

    def _grow(self, width: int, height: int) -> None:
        """Rebuild the scene with a film wide enough for a ``width`` x ``height`` pinhole render (with the
        same margin as at the start): the film's size is fixed once a Mitsuba scene is loaded."""
        self.wide_size = (max(self.wide_size[0], int(width * FOV_MARGIN) // 2 * 2 + 2),
                          max(self.wide_size[1], int(height * FOV_MARGIN) // 2 * 2 + 2))
        film = self._dict["sensor"]["film"]
        film["width"], film["height"] = self.wide_size
        self.scene = self.mi.load_dict(self._dict)
        self.params = self.mi.traverse(self.scene)
        if self.light_power_scale != 1.0:
            self.params["light.emitter.radiance.values"] = self.mi.Float(self.base_radiance * self.light_power_scale)

    def render(self, seed: int = 0) -> np.ndarray:
        # Mitsuba's stub types seed as mi.UInt32, yet mi.render takes a Python int (its own default is 0).
        wide = np.array(self.mi.render(self.scene, self.params, seed=seed))  # type: ignore[arg-type]
        plan = PinholePlan(self.wide_size[0], self.wide_size[1], self.focal, 0.0, self.camera.mitsuba_to_world())
        return self.camera.warp(wide, plan) * self.exposure

"""The fit preset: parameters changed in place render exactly what a scene built with
those parameters renders (same seed; tolerance 1e-4 relative for float32 round-off),
and a change of light power or exposure scales the image linearly (1e-5)."""

import dataclasses

import numpy as np


def test_in_place_changes_equal_a_fresh_build(mitsuba_variant):
    from renderer.rerender import FitRenderer
    from renderer.scene import load_scene

    spec = load_scene("cornell_cd")
    fit = FitRenderer(spec, resolution=(64, 48), spp=8)
    cam = fit.camera
    moved = dataclasses.replace(cam, fx=cam.fx * 1.03, fy=cam.fy * 1.03, cx=cam.cx + 1.5,
                                dist=(-0.05, 0.01, 0.0, 0.0, 0.0), world_to_camera=cam.world_to_camera.copy())
    moved.world_to_camera[:3, 3] += [0.004, -0.003, 0.006]
    fit.set(camera=moved, exposure=0.5, light_power_scale=2.0)
    in_place = fit.render(seed=3)

    fresh_spec = dataclasses.replace(spec, light=dataclasses.replace(spec.light, power_w=spec.light.power_w * 2.0),
                                     camera=dataclasses.replace(spec.camera, exposure=0.5))
    fresh = FitRenderer(fresh_spec, resolution=(64, 48), spp=8)
    fresh.set(camera=moved)
    rebuilt = fresh.render(seed=3)
    assert np.allclose(in_place, rebuilt, rtol=1e-4, atol=1e-6)


def test_light_power_and_exposure_scale_linearly(mitsuba_variant):
    from renderer.rerender import FitRenderer

    fit = FitRenderer("cornell_cd", resolution=(48, 36), spp=4)
    base = fit.render(seed=1)
    fit.set(light_power_scale=3.0, exposure=0.25)
    assert np.allclose(fit.render(seed=1), 0.75 * base, rtol=1e-5, atol=1e-7)

"""The scene's regions in an image: which shape each pixel's centre ray meets first.

A render of shape ids with the same camera: each pixel's centre ray (through the lens
model, renderer.camera.CameraModel.pixel_rays) cast into the Mitsuba scene
(``ray_intersect``) and the shape it meets first named from the scene's keys
(renderer.mitsuba_scene): cd, wall_left, wall_right, wall_back, ceiling, floor, light,
glass. (Mitsuba's ``aov`` integrator's ``shape_index`` is not the index of
``scene.shapes()`` once Mitsuba merges meshes, and its pinhole image would need a
nearest-neighbour warp; casting the camera's own rays avoids both.)

The report compares photo and render per region and takes its photometric scale from the
walls (reports.compare.images, reports.compare.regions); the targeted render (renderer.render_target)
samples each region to what the report measures there. Both use these masks.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from renderer.mitsuba_scene import scene_dict
from renderer.variant import set_variant

WALL_REGIONS = ("wall_left", "wall_right", "wall_back")


def region_name(shape_id: str) -> str | None:
    """A scene shape's region (renderer.mitsuba_scene's keys), or None for shapes that are none of them."""
    if shape_id.startswith("cd"):
        return "cd"
    if shape_id.startswith("glass"):
        return "glass"
    if shape_id == "light":
        return "light"
    for word in ("left", "right", "back"):
        if shape_id.startswith(f"{word}_wall"):
            return f"wall_{word}"
    for word in ("floor", "ceiling"):
        if shape_id.startswith(word):
            return word
    return None


def region_masks(spec, camera=None) -> dict[str, np.ndarray]:
    """Boolean masks (H, W) by region: which shape each pixel's centre ray meets first, with
    ``camera`` (the scene's by default), through the lens model (CameraModel.pixel_rays)."""
    set_variant()
    import drjit as dr  # deferred: start-up time; drjit loads after set_variant has set DRJIT_LIBLLVM_PATH
    import mitsuba as mi

    if camera is not None:
        spec = replace(spec, camera=replace(spec.camera, model=camera))
    camera = spec.camera.model
    d, _built = scene_dict(mi, spec, spp=1)
    scene = mi.load_dict(d, optimize=False)  # no merging: one shape per scene key
    v, u = np.mgrid[0:camera.height, 0:camera.width]
    origin, rays = camera.pixel_rays(np.stack([u.ravel(), v.ravel()], axis=1).astype(float))
    ray = mi.Ray3f(mi.Point3f(*[np.full(len(rays), c, np.float32) for c in origin]),
                   mi.Vector3f(*[np.ascontiguousarray(rays[:, i], np.float32) for i in range(3)]))
    hit = scene.ray_intersect(ray)
    masks: dict[str, np.ndarray] = {}
    for shape in scene.shapes():
        name = region_name(shape.id())
        if name is None:
            continue
        mine = np.array(dr.select(hit.is_valid(), hit.shape == mi.ShapePtr(shape), False)).reshape(camera.height, camera.width)
        masks[name] = masks.get(name, np.zeros(mine.shape, bool)) | mine
    return masks

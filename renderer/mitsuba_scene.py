"""A scene spec (renderer.scene) as a Mitsuba scene dict: the box, the light, the CDs and
gratings with their efficiency tables, the glass objects and the sensor.

The objects' spectra come from renderer.spectra, their meshes from renderer.meshes, their
placement from renderer.placement and the CDs' and gratings' tables from renderer.tables
(planned for the scene's camera by renderer.trace.planner when asked). The dict's shapes are
added in a fixed order (box quads, light, CDs, gratings, glass, sensor), which fixes the
render's bytes for a seed.
"""

from __future__ import annotations

import math

import numpy as np

from rcwa.materials import Material, material_from_spec
from renderer.meshes import annulus_mesh, quad_mesh
from renderer.placement import cd_top_center, frame_to, glass_cube_to_world, grating_to_world, light_to_world, transform
from renderer.plugins import register_plugins
from renderer.scene import CDSpec, GlassSpec, GratingSpec, SceneSpec, box_scale, cornell_data
from renderer.spectra import Curves, camera_sensitivities, irregular, light_spectrum
from renderer.tables import element_table
from renderer.trace.planner import planned_nodes


def light_dict(mi, light) -> dict:
    """The ceiling light (renderer.scene.LightSpec): a rectangle facing down whose emitter
    has total radiant power ``power_w``. Lambertian: Mitsuba's ``area``, radiance
    P / (pi A) times the normalised spectrum; ``cos_power`` n: renderer.emitter's
    ``cospower_area`` with radiance along the normal P / (A 2 pi / (n + 2)).
    """
    wl, s = light_spectrum(light.spectrum)
    area = light.size[0] * light.size[1]
    projected_solid_angle = math.pi if light.cos_power is None else 2 * math.pi / (light.cos_power + 2)
    radiance = irregular(wl, s * light.power_w / (projected_solid_angle * area * np.trapezoid(s, wl)))
    emitter = ({"type": "area", "radiance": radiance} if light.cos_power is None
               else {"type": "cospower_area", "cos_power": float(light.cos_power), "radiance": radiance})
    return {"type": "rectangle", "emitter": emitter, "to_world": mi.ScalarTransform4f(light_to_world(light).tolist())}


def scene_dict(mi, spec: SceneSpec, *, spp: int, integrator: str = "path", mode: str = "improved",
               max_depth: int = 8, plan: bool = False, progress: bool = True) -> tuple[dict, dict]:
    """The Mitsuba scene dict and what was built for it (tables, the pinhole plan).

    ``plan``: tables planned for this scene's camera (renderer.trace.planner): the nodes its
    rays read solved in full, the rest with fewer orders; for a render of one camera.
    Renders of many cameras (calibration's re-renders) use whole tables. ``progress``: a
    bar while a table is built."""
    register_plugins()
    # Mitsuba's direct integrator has no max_depth (it refuses unknown properties).
    depth = {"max_depth": max_depth} if integrator == "path" else {}
    scene: dict = {"type": "scene", "integrator": {"type": integrator, **depth}}
    scene.update(box_shapes(spec))
    scene["light"] = light_dict(mi, spec.light)
    sens = camera_sensitivities(spec.camera.sensitivities)
    built: dict = {"tables": []}
    nodes = planned_nodes(spec) if plan else {}
    for i, cd in enumerate(spec.cds):
        table = element_table(cd, sens, f"cd[{i}]", spec.source, nodes.get(f"cd[{i}]"), progress)
        built["tables"].append(str(table))
        scene.update(cd_shapes(mi, cd, i, table, mode))
    for i, g in enumerate(spec.gratings):
        table = element_table(g, sens, f"grating[{i}]", spec.source, nodes.get(f"grating[{i}]"), progress)
        built["tables"].append(str(table))
        scene[f"grating{i}"] = grating_shape(mi, g, table, mode)
    for i, glass in enumerate(spec.glass):
        scene[f"glass{i}"] = glass_shape(mi, glass)
    scene["sensor"], built["plan"] = sensor_dict(mi, spec.camera, spp)
    return scene, built


def box_shapes(spec: SceneSpec) -> dict[str, dict]:
    """The Cornell box's diffuse quads (``floor_white_0``, ``block_..._i``), the blocks only
    when ``box.blocks``; reflectances measured, or uniform where the scene sets a colour."""
    data = cornell_data()
    refl = data["reflectance"]
    spectra = {c: irregular(refl["wavelength_nm"], refl[c]) for c in ("white", "red", "green")}
    for colour in ("white", "red", "green"):
        if colour in spec.box:
            spectra[colour] = {"type": "uniform", "value": spec.box[colour]}
    shapes = {}
    for name, quad in data["geometry"].items():
        if name in ("units", "notes", "light") or ("block" in name and not spec.box["blocks"]):
            continue
        colour = name.rsplit("_", 1)[-1]
        quads = quad if "block" in name else [quad]
        for i, q in enumerate(quads):
            shapes[f"{name}_{i}"] = {"type": "ply", "filename": str(quad_mesh(q, box_scale(spec.box))), "face_normals": True,
                                     "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": spectra[colour]}}}
    return shapes


def cd_shapes(mi, cd: CDSpec, index: int, table, mode: str) -> dict[str, dict]:
    """CD ``index``: its annulus with the BWDF of ``table`` (``cd0``) and, with ``top_surface``,
    its flat polycarbonate top above it (``cd0_top``)."""
    from renderer.dielectric import bsdf_dict, mean_index  # deferred: imports mitsuba, and needs its variant set

    polycarbonate = _polycarbonate()
    R = frame_to(cd.normal, cd.rotation_deg)
    mesh = str(annulus_mesh(cd.inner_radius, cd.outer_radius))
    bwdf: dict[str, object] = {"type": "bwdf", "filename": str(table), "mapping": "radial", "mode": mode,
                               "center": [float(c) for c in cd.center]}  # the grooves' centre: radial at every hit
    if cd.top_surface and not cd.dispersion:  # the top at its mean index is the grating's superstrate
        bwdf["superstrate_index"] = mean_index(polycarbonate)
    shapes = {f"cd{index}": {"type": "ply", "filename": mesh, "to_world": mi.ScalarTransform4f(transform(cd.center, R).tolist()),
                             "bsdf": bwdf}}
    if cd.top_surface:
        shapes[f"cd{index}_top"] = {"type": "ply", "filename": mesh,
                                    "to_world": mi.ScalarTransform4f(transform(cd_top_center(cd), R).tolist()),
                                    "bsdf": bsdf_dict(polycarbonate, dispersion=cd.dispersion)}
    return shapes


def _polycarbonate() -> Material:
    """The CDs' polycarbonate (rcwa.materials), for their tops and superstrate index."""
    return material_from_spec("polycarbonate")


def grating_shape(mi, grating: GratingSpec, table, mode: str) -> dict:
    """A grating plate: a rectangle with the BWDF of ``table``, one groove direction everywhere."""
    return {"type": "rectangle", "to_world": mi.ScalarTransform4f(grating_to_world(grating).tolist()),
            "bsdf": {"type": "bwdf", "filename": str(table), "mapping": "constant", "mode": mode}}


def glass_shape(mi, glass: GlassSpec) -> dict:
    """A glass sphere or cube, a smooth dielectric of its material (dispersive or at its mean index)."""
    from renderer.dielectric import bsdf_dict  # deferred: imports mitsuba, and needs its variant set

    bsdf = bsdf_dict(material_from_spec(glass.material), dispersion=glass.dispersion)
    if glass.shape == "sphere":
        return {"type": "sphere", "center": list(glass.center), "radius": glass.size, "bsdf": bsdf}
    return {"type": "cube", "bsdf": bsdf, "to_world": mi.ScalarTransform4f(glass_cube_to_world(glass).tolist())}


def sensor_dict(mi, camera, spp: int):
    """Mitsuba's sensor for a scene camera: the ideal pinhole plan (renderer.camera) with a
    spectral film whose three channels are the camera's sensitivities (camera RGB).
    """
    plan = camera.model.pinhole_plan()
    curves: Curves = camera_sensitivities(camera.sensitivities)
    film = {f"channel_{c}": irregular(w, v) for c, (w, v) in zip("rgb", curves, strict=True)}
    sensor = plan.sensor_dict(mi, spp)
    sensor["film"] = {"type": "specfilm", "width": plan.width, "height": plan.height, "rfilter": {"type": "box"},
                      "component_format": "float32", **film}
    return sensor, plan


def cropped_sensor(sensor: dict, offset: tuple[int, int], size: tuple[int, int]) -> dict:
    """``sensor`` (sensor_dict's) rendering only a window of its film: Mitsuba's film crop
    (``crop_offset_x``, ``crop_offset_y``, ``crop_width``, ``crop_height``; the pixels keep
    their place in the full frame, so a crop's pixel is the full render's same pixel)."""
    film = dict(sensor["film"], crop_offset_x=int(offset[0]), crop_offset_y=int(offset[1]),
                crop_width=int(size[0]), crop_height=int(size[1]))
    return dict(sensor, film=film)

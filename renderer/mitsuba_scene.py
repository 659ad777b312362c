"""Build a Mitsuba scene from a scene spec (renderer.scene): geometry, spectra, CD tables.

Spectra are Mitsuba ``irregular`` spectra over 360-830 nm; data that stop inside that
range (the Cornell reflectances, 400-700 nm) are held constant beyond their ends.
Meshes (box quads, CD annuli) are PLY files in the user's cache (workbench.core.cache,
``meshes/``) named by the hash of their text, written atomically under the entry's lock
and checked against their name when reused. A CD's or grating's efficiency table is the
one its ``table = { path = ... }`` names (checked: finished, intact, built for the
element's structure), or else built through the table cache (``tables/``, named by the
request's content hash) when missing; either is checked to cover where the camera sees.
"""

from __future__ import annotations

import hashlib
import math
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from renderer.scene import CD_TOP_THICKNESS_M, MM, SPECTRAL_RANGE_NM, SceneSpec, box_scale, cornell_data
from workbench.core.cache import entry_lock, entry_path
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text

CD_SEGMENTS = 256
GRID_NM = np.arange(SPECTRAL_RANGE_NM[0], SPECTRAL_RANGE_NM[1] + 1e-9, 5.0)


def irregular(wavelengths, values) -> dict:
    wl = np.asarray(wavelengths, dtype=float)
    vals = np.asarray(values, dtype=float)
    if wl[0] > SPECTRAL_RANGE_NM[0]:
        wl, vals = np.r_[SPECTRAL_RANGE_NM[0], wl], np.r_[vals[0], vals]
    if wl[-1] < SPECTRAL_RANGE_NM[1]:
        wl, vals = np.r_[wl, SPECTRAL_RANGE_NM[1]], np.r_[vals, vals[-1]]
    return {"type": "irregular", "wavelengths": ", ".join(f"{w:g}" for w in wl), "values": ", ".join(f"{x:.6g}" for x in vals)}


def light_spectrum(name: str) -> tuple[np.ndarray, np.ndarray]:
    if name == "flat":
        return GRID_NM, np.ones_like(GRID_NM)
    if name == "cornell":
        e = cornell_data()["light_emission"]
        return GRID_NM, np.interp(GRID_NM, e["wavelength_nm"], e["value"])
    import colour

    sd = colour.SDS_ILLUMINANTS[name]
    return GRID_NM, np.interp(GRID_NM, sd.wavelengths, sd.values, left=0.0, right=0.0)


def camera_sensitivities(name: str) -> list[tuple[np.ndarray, np.ndarray]]:
    import colour

    msds = colour.MSDS_CAMERA_SENSITIVITIES[name]
    return [(msds.wavelengths, msds.values[:, i]) for i in range(3)]


def _write_ply(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray | None = None) -> Path:
    lines = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}",
             "property float x", "property float y", "property float z"]
    if uv is not None:
        lines += ["property float u", "property float v"]
    lines += [f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    rows = [" ".join(f"{c:.9g}" for c in (list(p) + (list(uv[i]) if uv is not None else []))) for i, p in enumerate(vertices)]
    rows += [f"3 {a} {b} {c}" for a, b, c in faces]
    text = "\n".join(lines + rows) + "\n"
    digest = hashlib.sha256(text.encode()).hexdigest()[:20]
    path = entry_path("meshes", digest + ".ply")
    if not _mesh_intact(path, digest):
        with entry_lock(path):
            if not _mesh_intact(path, digest):  # another process may have written it meanwhile
                atomic_write_text(path, text)
    return path


def _mesh_intact(path: Path, digest: str) -> bool:
    """A cached mesh is reused only when its bytes still hash to its name."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()[:20] == digest
    except OSError:
        return False


def quad_mesh(points_mm, scale=(1.0, 1.0, 1.0)) -> Path:
    p = np.asarray(points_mm, dtype=float) * MM * np.asarray(scale)
    return _write_ply(p, np.array([[0, 1, 2], [0, 2, 3]]))


def annulus_mesh(inner: float, outer: float) -> Path:
    """An annulus in the xy-plane (normal +z) with u radial and v the angle (dp/du radial)."""
    angles = np.linspace(0, 2 * np.pi, CD_SEGMENTS + 1)
    ring = lambda r: np.stack([r * np.cos(angles), r * np.sin(angles), np.zeros_like(angles)], 1)  # noqa: E731
    vertices = np.concatenate([ring(inner), ring(outer)])
    n = len(angles)
    uv = np.concatenate([np.stack([np.zeros(n), angles / (2 * np.pi)], 1), np.stack([np.ones(n), angles / (2 * np.pi)], 1)])
    faces = []
    for i in range(CD_SEGMENTS):
        faces += [[i, n + i, n + i + 1], [i, n + i + 1, i + 1]]
    return _write_ply(vertices, np.array(faces), uv)


def frame_to(normal, rotation_deg: float) -> np.ndarray:
    """Rotation taking +z to ``normal``, after rotating by ``rotation_deg`` about z."""
    n = np.asarray(normal, dtype=float)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, n)
    s, c = np.linalg.norm(axis), float(np.dot(z, n))
    if s < 1e-12:
        R = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    else:
        k = axis / s
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        R = np.eye(3) + s * K + (1 - c) * K @ K
    a = math.radians(rotation_deg)
    Rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    return R @ Rz


def transform(translation, rotation: np.ndarray, scale=(1.0, 1.0, 1.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation @ np.diag(scale)
    T[:3, 3] = translation
    return T


@dataclass(frozen=True)
class TablePlan:
    """An element's efficiency table: where it is, the request it holds (rcwa.table's key),
    and the settings to build it with (None for a table the scene names by ``path``).
    """

    path: Path
    key: str
    structure: Any
    settings: Any
    nodes: Any = None  # rcwa.table.NodePlan of a planned table (None: the whole table)
    fallback: TablePlan | None = None  # for another plan's table serving this one: this plan's own, if that one is damaged


# rcwa.table.settings_for names the command line's options; a scene's table = {...} has these keys
SCENE_TABLE_KEYS = {"--preset": "preset", "--wavelengths": "wavelengths", "--orders": "orders", "--keep-orders": "keep",
                    "--theta-step": "theta_step", "--phi-step": "phi_step", "--theta-range": "theta_range",
                    "--phi-range": "phi_range", "--pol": "pol", "--factorization": "factorization"}


def scene_settings_for(structure, preset: str, options: dict, where: str, scene_file: str | None):
    """rcwa.table.settings_for of a scene element's table options; a refused option names the
    scene file and field (``cd[0].table.keep``), not the command line's (``--keep-orders``)."""
    from rcwa.table import check_materials, settings_for

    try:
        settings = settings_for(structure, preset, **options)
    except UserInputError as exc:
        raise _in_scene(exc, where, scene_file) from None
    try:
        check_materials(structure, settings)
    except UserInputError as exc:  # names the structure's field; the scene asked for the wavelengths
        raise UserInputError(f"{exc.reason.split(';')[0]} (in {exc.file}, field '{exc.field}')", file=scene_file,
                             field=f"{where}.table.wavelengths", expected="wavelengths inside every material's data",
                             got=options.get("wavelengths", f"the {preset} preset's")) from None
    return settings


def _in_scene(exc: UserInputError, where: str, scene_file: str | None) -> UserInputError:
    """``exc`` about a command-line option (SCENE_TABLE_KEYS) as the scene field it came from."""
    key = SCENE_TABLE_KEYS.get(exc.field or "")
    if key is None:
        return exc
    expected = (exc.expected or "").replace(f"--{key.replace('_', '-')}", key) or None
    return UserInputError(exc.reason, file=scene_file, field=f"{where}.table.{key}", expected=expected, got=exc.got)


def table_settings(element, structure, where: str = "element", scene_file: str | None = None):
    """The table settings of an element's ``table = {...}`` (not ``path``): the scene's
    options, with light from below for a see-through element (scene_settings_for)."""
    options = {k: v for k, v in dict(element.table).items() if k != "path"}
    preset = options.pop("preset", "draft")
    eps = np.asarray(structure.substrate.epsilon(np.array([550.0])))
    if np.all((eps.imag == 0) & (eps.real > 0)):
        options.setdefault("both_sides", True)  # see-through: light from below too
    return scene_settings_for(structure, preset, options, where, scene_file)


def table_plan(element, where: str = "element", scene_file: str | None = None, nodes=None) -> TablePlan:
    """Where a CD's or grating's table is and what it holds, without building it.

    ``nodes`` (rcwa.table.NodePlan, from renderer.planner): a planned table, unless the
    whole table is in the cache already (it serves every plan)."""
    import rcwa
    from rcwa.table import planned, read_table_metadata, request_key

    structure = rcwa.load_structure(element.structure)
    options = dict(element.table)
    if "path" in options:  # alone (renderer.scene checks), relative paths already resolved against the scene file
        path = Path(options["path"])
        try:
            meta = read_table_metadata(path)
        except UserInputError as exc:
            raise UserInputError(f"{path}: {exc.reason}", file=scene_file, field=f"{where}.table.path",
                                 expected=exc.expected) from None
        return TablePlan(path, meta["key"], structure, None)
    settings = table_settings(element, structure, where, scene_file)
    key = request_key(structure, settings)
    whole = TablePlan(entry_path("tables", f"{structure.name}-{key[:16]}.zarr"), key, structure, settings)
    if nodes is None or _finished_table(whole.path, key) is not None:
        return whole
    settings = planned(settings, nodes)
    planned_key = request_key(structure, settings)
    own = TablePlan(whole.path.with_name(f"{whole.path.stem}-planned-{planned_key[:12]}.zarr"), planned_key, structure,
                    settings, nodes)
    if own.path.exists():  # this plan's own table: build_table serves it, resumes it or computes damaged chunks again
        return own
    return _planned_superset(whole.path, nodes, own) or own


def _finished_table(path: Path, key: str | None = None) -> dict | None:
    """The metadata of a finished table at ``path`` (of request ``key`` when given), or None."""
    from rcwa.table import read_table_metadata

    try:
        meta = read_table_metadata(path)
    except UserInputError:
        return None
    return meta if meta.get("complete") and key in (None, meta.get("key")) else None


def _planned_superset(whole: Path, nodes, own: TablePlan) -> TablePlan | None:
    """A finished planned table of the same request whose exactly solved nodes include
    ``nodes``' with the same fill: it serves this plan (another camera's plan, a run's plan
    for the scene's camera with a margin). ``own`` (this plan's table) is its fallback."""
    import zarr

    for path in sorted(whole.parent.glob(f"{whole.stem}-planned-*.zarr")):
        meta = _finished_table(path)
        if meta is None or meta.get("planned", {}).get("fill_orders") != list(nodes.fill_orders):
            continue
        try:
            mask = np.asarray(zarr.open_array(str(path / "planned_nodes"), mode="r")[...], bool)
        except Exception:  # unreadable: not a candidate
            continue
        if mask.shape == nodes.mask.shape and not np.any(nodes.mask & ~mask):
            return TablePlan(path, meta["key"], own.structure, None, fallback=own)  # built: checked like a named table
    return None


def planned_nodes(spec: SceneSpec, margin: int = 0) -> dict[str, Any]:
    """The planner's rcwa.table.NodePlan per element key (``cd[0]``).

    ``margin``: grow each mask by this many grid nodes in theta and phi, so that the
    table also serves cameras near this one (a run plans with the scene's camera and
    renders with the fitted one; _planned_superset then finds the table)."""
    from scipy.ndimage import binary_dilation

    from rcwa.table import NodePlan
    from renderer.planner import plan_scene

    plan = plan_scene(spec, measure_cost=False)
    nodes = {e.key: e.node_plan() for e in plan.elements}
    if margin:
        grow = np.ones((1, 2 * margin + 1, 2 * margin + 1), bool)
        nodes = {k: NodePlan(binary_dilation(n.mask, grow), n.fill_orders) for k, n in nodes.items()}
    return nodes


def table_keys(spec: SceneSpec) -> list[str]:
    """The request keys of a scene's tables (their content, wherever the cache is), in order."""
    elements = ([(f"cd[{i}]", cd) for i, cd in enumerate(spec.cds)]
                + [(f"grating[{i}]", g) for i, g in enumerate(spec.gratings)])
    return [table_plan(element, where, spec.source).key for where, element in elements]


def element_table(element, camera_sens, where: str = "element", scene_file: str | None = None, nodes=None,
                  progress: bool = True) -> Path:
    """The efficiency table of a CD or grating: the one its scene names (checked), or built
    through the table cache (planned with ``nodes``: see table_plan). ``where`` (``cd[0]``)
    and ``scene_file`` locate errors; ``progress``: a bar while a table is built.
    """
    from rcwa.table import build_table
    from renderer.checks import require_table_covers_camera

    plan = table_plan(element, where, scene_file, nodes)
    if plan.settings is None:
        try:
            wavelengths = _check_named_table(plan, where, scene_file)
        except UserInputError as exc:
            if plan.fallback is None:  # a table the scene names: the user's to repair
                raise
            print(f"{plan.path}: not used ({exc.reason}); building this camera's own table", file=sys.stderr)
            plan = plan.fallback
    if plan.settings is not None:
        try:
            report = build_table(plan.structure, plan.settings, plan.path, progress=progress, force=True,  # the cache's
                                 nodes=plan.nodes)
            for note in report.notes:  # damaged chunks computed again: say so, as `rcwa table` does
                print(f"{plan.path}: {note}", file=sys.stderr)
        except UserInputError as exc:  # e.g. wavelengths outside a material's data: say which scene field asked
            raise UserInputError(f"its table cannot be built: {exc}", file=scene_file, field=f"{where}.table") from None
        wavelengths = np.asarray(plan.settings.wavelengths_nm)
    wl = np.unique(np.concatenate([w for w, _ in camera_sens]))
    curves = np.stack([np.interp(wl, w, s, left=0, right=0) for w, s in camera_sens])
    require_table_covers_camera(str(plan.path), wavelengths, wl, curves)
    return plan.path


def _check_named_table(plan: TablePlan, where: str, scene_file: str | None) -> np.ndarray:
    """A table a scene names must be finished, intact, built for the element's structure,
    and hold light from below when the element is see-through; its wavelengths.
    """
    from rcwa.table import open_table

    field = f"{where}.table.path"
    try:
        table = open_table(plan.path)  # finished, every chunk's checksum
    except UserInputError as exc:
        raise UserInputError(f"{plan.path}: {exc.reason}", file=scene_file, field=field) from None
    if tomllib.loads(table.meta["structure_text"]) != tomllib.loads(plan.structure.text):
        raise UserInputError(f"{plan.path} was built for another structure ({table.meta['structure_source']}), not the "
                             f"element's ({plan.structure.source})", file=scene_file, field=field,
                             expected=f"a table built with `workbench rcwa table {plan.structure.source} ...`")
    arrays = set(table.meta["arrays"])
    if "T" in arrays and not {"R_below", "T_below"} <= arrays:
        raise UserInputError(f"{plan.path}: the element is see-through (its substrate transmits) and needs light from "
                             "both sides", file=scene_file, field=field, expected="a table built with --both-sides")
    return table.wavelengths_nm


def register_plugins() -> None:
    """Register the renderer's Mitsuba plugins: bwdf, cospower_area, dispersive_dielectric."""
    from renderer import bwdf, dielectric, emitter

    for module in (bwdf, emitter, dielectric):
        module.register()


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
    down = frame_to([0.0, -1.0, 0.0], 0.0)
    placed = transform(light.center, down, (light.size[0] / 2, light.size[1] / 2, 1))
    return {"type": "rectangle", "emitter": emitter, "to_world": mi.ScalarTransform4f(placed.tolist())}


def scene_dict(mi, spec: SceneSpec, *, spp: int, integrator: str = "path", mode: str = "improved",
               max_depth: int = 8, plan: bool = False, progress: bool = True) -> tuple[dict, dict]:
    """The Mitsuba scene dict and what was built for it (tables, the pinhole plan).

    ``plan``: tables planned for this scene's camera (renderer.planner): the nodes its
    rays read solved in full, the rest with fewer orders; for a render of one camera.
    Renders of many cameras (calibration's re-renders) use whole tables. ``progress``: a
    bar while a table is built."""
    register_plugins()
    from renderer.dielectric import bsdf_dict, mean_index

    data = cornell_data()
    refl = data["reflectance"]
    spectra = {c: irregular(refl["wavelength_nm"], refl[c]) for c in ("white", "red", "green")}
    for colour in ("white", "red", "green"):
        if colour in spec.box:
            spectra[colour] = {"type": "uniform", "value": spec.box[colour]}
    # Mitsuba's direct integrator has no max_depth (it refuses unknown properties).
    depth = {"max_depth": max_depth} if integrator == "path" else {}
    scene: dict = {"type": "scene", "integrator": {"type": integrator, **depth}}
    for name, quad in data["geometry"].items():
        if name in ("units", "notes", "light") or ("block" in name and not spec.box["blocks"]):
            continue
        colour = name.rsplit("_", 1)[-1]
        quads = quad if "block" in name else [quad]
        for i, q in enumerate(quads):
            scene[f"{name}_{i}"] = {"type": "ply", "filename": str(quad_mesh(q, box_scale(spec.box))), "face_normals": True,
                                    "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": spectra[colour]}}}
    scene["light"] = light_dict(mi, spec.light)
    sens = camera_sensitivities(spec.camera.sensitivities)
    built: dict = {"tables": []}
    from rcwa.materials import material_from_spec

    polycarbonate = material_from_spec("polycarbonate")
    nodes = planned_nodes(spec) if plan else {}
    for i, cd in enumerate(spec.cds):
        table = element_table(cd, sens, f"cd[{i}]", spec.source, nodes.get(f"cd[{i}]"), progress)
        built["tables"].append(str(table))
        R = frame_to(cd.normal, cd.rotation_deg)
        mesh = str(annulus_mesh(cd.inner_radius, cd.outer_radius))
        bwdf: dict[str, object] = {"type": "bwdf", "filename": str(table), "mapping": "radial", "mode": mode,
                                   "center": [float(c) for c in cd.center]}  # the grooves' centre: radial at every hit
        if cd.top_surface and not cd.dispersion:  # the top at its mean index is the grating's superstrate
            bwdf["superstrate_index"] = mean_index(polycarbonate)
        scene[f"cd{i}"] = {"type": "ply", "filename": mesh, "to_world": mi.ScalarTransform4f(transform(cd.center, R).tolist()),
                           "bsdf": bwdf}
        if cd.top_surface:
            top = np.asarray(cd.center) + CD_TOP_THICKNESS_M * np.asarray(cd.normal)
            scene[f"cd{i}_top"] = {"type": "ply", "filename": mesh,
                                   "to_world": mi.ScalarTransform4f(transform(top, R).tolist()),
                                   "bsdf": bsdf_dict(polycarbonate, dispersion=cd.dispersion)}
    for i, g in enumerate(spec.gratings):
        table = element_table(g, sens, f"grating[{i}]", spec.source, nodes.get(f"grating[{i}]"), progress)
        built["tables"].append(str(table))
        R = frame_to(g.normal, g.rotation_deg)
        plate = transform(g.center, R, (g.size[0] / 2, g.size[1] / 2, 1.0))
        scene[f"grating{i}"] = {"type": "rectangle", "to_world": mi.ScalarTransform4f(plate.tolist()),
                                "bsdf": {"type": "bwdf", "filename": str(table), "mapping": "constant", "mode": mode}}
    for i, glass in enumerate(spec.glass):
        bsdf = bsdf_dict(material_from_spec(glass.material), dispersion=glass.dispersion)
        if glass.shape == "sphere":
            scene[f"glass{i}"] = {"type": "sphere", "center": list(glass.center), "radius": glass.size, "bsdf": bsdf}
        else:
            c, s = math.cos(math.radians(glass.rotation_deg)), math.sin(math.radians(glass.rotation_deg))
            R = frame_to([0, 0, 1], 0.0) @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])  # about y
            cube = transform(glass.center, R, (glass.size / 2,) * 3)
            scene[f"glass{i}"] = {"type": "cube", "bsdf": bsdf, "to_world": mi.ScalarTransform4f(cube.tolist())}
    scene["sensor"], built["plan"] = sensor_dict(mi, spec.camera, spp)
    return scene, built


def sensor_dict(mi, camera, spp: int):
    """Mitsuba's sensor for a scene camera: the ideal pinhole plan (renderer.camera) with a
    spectral film whose three channels are the camera's sensitivities (camera RGB).
    """
    plan = camera.model.pinhole_plan()
    curves = camera_sensitivities(camera.sensitivities)
    film = {f"channel_{c}": irregular(w, v) for c, (w, v) in zip("rgb", curves, strict=True)}
    sensor = plan.sensor_dict(mi, spp)
    sensor["film"] = {"type": "specfilm", "width": plan.width, "height": plan.height, "rfilter": {"type": "box"},
                      "component_format": "float32", **film}
    return sensor, plan

"""Scene files (TOML): the Cornell box, its LED light, CDs, glass and the camera.

Format (renderer/scenes/cornell_cd.toml is a complete example). Lengths in metres,
angles in degrees, wavelengths in nm.

[box]     ``model = "cornell"``: the measured box (renderer/data/cornell_box.json: the
          geometry in mm is scaled to metres and its open front faces -z), white floor,
          ceiling and back wall, red left and green right walls with the measured
          reflectances (``white``/``red``/``green`` may override them with a number);
          ``size`` [w, h, d] in metres rescales the measured box (default 0.556, 0.549,
          0.559); ``blocks = true`` adds the two white blocks.
[light]   an area light in the ceiling, facing down: ``center``, ``size`` ([x, z]),
          ``power_w`` (the total radiant power, whatever the profile), ``spectrum``:
          ``"flat"``, ``"cornell"`` (the measured relative emission) or a CIE LED
          illuminant (``"LED-B1"``..``"LED-B5"``, ``"LED-BH1"``, ``"LED-RGB1"``, ``"LED-V1"``,
          ``"LED-V2"``; colour-science's data), ``emission_profile``: ``"lambertian"``
          (default; Mitsuba's area light) or ``{ cos_power = n }`` (n >= 0): radiance
          L0 cos^n(theta) about the normal, an LED array with lenses / a narrower beam,
          L0 = power_w / (A 2 pi / (n + 2)) (renderer.emitter; n = 0 is Lambertian).
          The default light is the measured one, scaled with ``box.size``.
[[cd]]    ``center``, ``normal``, ``rotation_deg``, ``outer_radius`` (0.060),
          ``inner_radius`` (0.0075), ``structure`` (built-in name or file; relative to the
          scene file), ``table`` (options of ``workbench rcwa table``: preset, orders, ...),
          ``top_surface`` (true: a 1.2 mm polycarbonate face above the grating),
          ``dispersion`` (true, default: the top's index is polycarbonate's n(lambda),
          renderer.dielectric; false: Mitsuba's dielectric at the mean index).
[[grating]] a flat grating plate (a rectangle): ``center``, ``normal``, ``size`` [w, h],
          ``rotation_deg`` (of the grating vector about the normal), ``structure``,
          ``table``; see-through structures get their table with both sides.
[[glass]] ``shape = "cube" | "sphere"``, ``center``, ``size`` (cube edge) or ``radius``,
          ``rotation_deg`` (about y), ``material`` (built-in name or index), ``dispersion``
          (true, default: n(lambda) from the material, renderer.dielectric; false:
          Mitsuba's dielectric at the mean of n over 360-830 nm).
[camera]  ``resolution`` [w, h], ``look_at`` {origin, target, up} or ``world_to_camera``
          (4 x 4, OpenCV axes, metres: what calibration writes), ``fov_deg`` (horizontal)
          or ``focal_mm`` with ``sensor_mm`` [w, h] or ``focal_px`` [fx, fy] (pixels),
          ``principal_offset_px`` (from the image centre, (w - 1) / 2, (h - 1) / 2), ``dist``
          [k1, k2, p1, p2, k3] (OpenCV), ``exposure`` (a scale on camera RGB),
          ``sensitivities`` (a colour-science camera, default "Nikon 5100 (NPL)"),
          ``response`` ("linear", { gamma = G } or { points = [[x, y], ...] }; used only
          to compare with non-raw photos; renderer.response).
[fit]     the scene fit's free parameters, named as the file's fields
          (``"cd[0].structure.period" = { bounds = [1.5, 1.7] }``; renderer.fit_parameters).

Placement checks when a scene loads (docs/scene_format.md): the light in the ceiling, every object in the
box, each CD and opaque grating lit on its front, the camera in or before the box looking in; warnings
(``SceneSpec.warnings``) for a camera that sees little of the scene.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from rcwa.factorization import FACTORIZATION_RULES
from rcwa.materials import material_from_spec
from rcwa.structure import BUILTIN_STRUCTURES, load_structure
from renderer.camera import CameraModel, look_at
from renderer.camera_coverage import camera_view_warnings, check_camera_placement
from renderer.fit_parameters import FitTable, parse_fit_table
from renderer.lens import LENS_MODELS
from renderer.response import ResponseCurve
from workbench.core import validation as v
from workbench.core.errors import UserInputError

BUILTIN_SCENES: tuple[str, ...] = ("cornell_cd", "cornell_cd_view2", "grating2d_gold")
MM = 1e-3
CD_TOP_THICKNESS_M = 1.2e-3
LED_SPECTRA = ("LED-B1", "LED-B2", "LED-B3", "LED-B4", "LED-B5", "LED-BH1", "LED-RGB1", "LED-V1", "LED-V2")
SPECTRAL_RANGE_NM = (360.0, 830.0)
# The light's power within float32's range: its spectral radiance (power over area, solid angle and the
# spectrum, renderer.emitter) must neither overflow (1e308 W is inf in float32) nor underflow to zero (Mitsuba
# then stops with "no probability mass found", measured at 1e-46 W). A nanowatt to a gigawatt: 10 and 8 orders
# of magnitude around the Cornell box's 10 W lamp.
MIN_LIGHT_POWER_W, MAX_LIGHT_POWER_W = 1e-9, 1e9


@dataclass(frozen=True)
class LightSpec:
    center: tuple[float, float, float]
    size: tuple[float, float]
    power_w: float
    spectrum: str
    cos_power: float | None = None  # emission profile: None is Lambertian (Mitsuba's area light)


@dataclass(frozen=True)
class CDSpec:
    center: tuple[float, float, float]
    normal: tuple[float, float, float]
    rotation_deg: float
    outer_radius: float
    inner_radius: float
    structure: str
    table: dict
    top_surface: bool
    dispersion: bool = True


@dataclass(frozen=True)
class GratingSpec:
    center: tuple[float, float, float]
    normal: tuple[float, float, float]
    size: tuple[float, float]
    rotation_deg: float
    structure: str
    table: dict


@dataclass(frozen=True)
class GlassSpec:
    shape: str
    center: tuple[float, float, float]
    size: float
    rotation_deg: float
    material: Any
    dispersion: bool = True


@dataclass(frozen=True)
class CameraSpec:
    model: CameraModel
    exposure: float
    sensitivities: str
    response: "ResponseCurve" = field(default_factory=lambda: ResponseCurve())


@dataclass(frozen=True)
class SceneSpec:
    name: str
    source: str
    text: str
    box: dict
    light: LightSpec
    camera: CameraSpec
    cds: tuple[CDSpec, ...] = ()
    glass: tuple[GlassSpec, ...] = ()
    gratings: tuple[GratingSpec, ...] = ()
    base_dir: Path | None = field(default=None, compare=False)
    fit: FitTable | None = field(default=None, compare=False)  # the free parameters of a scene fit ([fit])
    warnings: tuple[str, ...] = field(default=(), compare=False)  # legitimate but suspicious (camera_view_warnings)


def cornell_data() -> dict:
    return json.loads(resources.files("renderer.data").joinpath("cornell_box.json").read_text())


def load_scene(name_or_path: str | Path) -> SceneSpec:
    name = str(name_or_path)
    if name in BUILTIN_SCENES:
        text = resources.files("renderer.scenes").joinpath(f"{name}.toml").read_text()
        return parse_scene(text, source=f"<built-in {name}>", base_dir=None)
    path = Path(name)
    if not path.exists() and not v.looks_like_path(name):
        raise UserInputError("no such scene", field="scene",
                             expected=f"a built-in name ({', '.join(BUILTIN_SCENES)}) or a TOML file", got=name)
    return parse_scene(v.read_text_file(path, "scene"), source=str(path), base_dir=path.parent)


def parse_scene(text: str, *, source: str, base_dir: Path | None) -> SceneSpec:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserInputError(f"not valid TOML ({exc})", file=source) from None
    try:
        return _parse(data, source, text, base_dir)
    except UserInputError as exc:
        raise exc.located(file=source) from None


def _parse(data: dict, source: str, text: str, base_dir: Path | None) -> SceneSpec:
    v.reject_unknown(data, {"name", "description", "box", "light", "cd", "glass", "grating", "camera", "fit"}, "")
    box = _parse_box(v.required(data, "box", ""))
    light = _parse_light(v.required(data, "light", ""), box)
    cds = tuple(_parse_cd(c, f"cd[{i}]", base_dir) for i, c in enumerate(data.get("cd", [])))
    glass = tuple(_parse_glass(g, f"glass[{i}]") for i, g in enumerate(data.get("glass", [])))
    gratings = tuple(_parse_grating(g, f"grating[{i}]", base_dir) for i, g in enumerate(data.get("grating", [])))
    camera = _parse_camera(v.required(data, "camera", ""))
    pose_field = "camera.world_to_camera" if "world_to_camera" in data["camera"] else "camera.look_at"
    warnings = _check_placement(box, light, cds, gratings, glass, camera.model, pose_field)
    fit = parse_fit_table(data.get("fit"), cds, light)
    return SceneSpec(str(data.get("name", "scene")), source, text, box, light, camera, cds, glass, gratings, base_dir,
                     fit, warnings)


def _parse_box(d: Any) -> dict:
    if not isinstance(d, dict):
        raise UserInputError("must be a table", field="box", got=d)
    v.reject_unknown(d, {"model", "blocks", "white", "red", "green", "size"}, "box.")
    model = d.get("model", "cornell")
    if model != "cornell":
        raise UserInputError("unknown box model", field="box.model", expected='"cornell"', got=model)
    out = {"model": model, "blocks": bool(d.get("blocks", False))}
    if "size" in d:
        out["size"] = v.vector(d["size"], "box.size", 3, positive=True)
    for colour in ("white", "red", "green"):
        if colour in d:
            value = v.number(d[colour], f"box.{colour}")
            if not 0 <= value <= 1:
                raise UserInputError("a reflectance must be in [0, 1]", field=f"box.{colour}", got=value)
            out[colour] = value
    return out


def _parse_light(d: Any, box: dict) -> LightSpec:
    if not isinstance(d, dict):
        raise UserInputError("must be a table", field="light", got=d)
    v.reject_unknown(d, {"center", "size", "power_w", "spectrum", "emission_profile"}, "light.")
    spectrum = d.get("spectrum", "flat")
    if spectrum not in ("flat", "cornell", *LED_SPECTRA):
        raise UserInputError("unknown light spectrum", field="light.spectrum",
                             expected=f"flat, cornell or one of {LED_SPECTRA}", got=spectrum)
    geometry = cornell_data()["geometry"]["light"]
    pts = np.asarray(geometry) * MM * box_scale(box)  # the measured light, scaled with the box (x 1.0 when unscaled)
    cx, cy, cz = (float(c) for c in pts.mean(axis=0) - [0, 1e-4, 0])  # 0.1 mm below the ceiling
    default_center = (cx, cy, cz)
    default_size = (float(np.ptp(pts[:, 0])), float(np.ptp(pts[:, 2])))
    return LightSpec(
        center=v.point(d["center"], "light.center") if "center" in d else default_center,
        size=v.pair(d["size"], "light.size", positive=True) if "size" in d else default_size,
        power_w=v.number(d.get("power_w", 10.0), "light.power_w",
                         at_least=MIN_LIGHT_POWER_W, at_most=MAX_LIGHT_POWER_W),
        spectrum=spectrum,
        cos_power=_emission_profile(d.get("emission_profile", "lambertian")),
    )


def _emission_profile(value: Any) -> float | None:
    """``"lambertian"`` -> None; ``{ cos_power = n }`` -> n (finite, >= 0)."""
    where = "light.emission_profile"
    expected = '"lambertian" or { cos_power = n } with n >= 0'
    if value == "lambertian":
        return None
    if not isinstance(value, dict):
        raise UserInputError("unknown emission profile", field=where, expected=expected, got=value)
    v.reject_unknown(value, {"cos_power"}, f"{where}.")
    n = v.number(v.required(value, "cos_power", f"{where}."), f"{where}.cos_power", nonnegative=True)
    if not math.isfinite(n):
        raise UserInputError("must be finite", field=f"{where}.cos_power", expected="a number >= 0", got=n)
    return n


def _flag(d: dict, key: str, where: str, default: bool) -> bool:
    value = d.get(key, default)
    if not isinstance(value, bool):
        raise UserInputError("must be true or false", field=f"{where}.{key}", got=value)
    return value


def _parse_cd(d: Any, where: str, base_dir: Path | None) -> CDSpec:
    if not isinstance(d, dict):
        raise UserInputError("must be a table", field=where, got=d)
    v.reject_unknown(d, {"center", "normal", "rotation_deg", "outer_radius", "inner_radius", "structure", "table", "top_surface",
                         "dispersion"}, f"{where}.")
    outer = v.number(d.get("outer_radius", 0.060), f"{where}.outer_radius", positive=True)
    inner = v.number(d.get("inner_radius", 0.0075), f"{where}.inner_radius", nonnegative=True)
    if inner >= outer:
        raise UserInputError("the hole must be smaller than the disc", field=f"{where}.inner_radius",
                             expected=f"< {outer}", got=inner)
    structure = _structure_reference(d.get("structure", "cd"), f"{where}.structure", base_dir)
    normal = _normal(d.get("normal", [0.0, 1.0, 0.0]), f"{where}.normal")
    table = _table_options(d.get("table", {"preset": "draft"}), f"{where}.table", base_dir)
    return CDSpec(v.point(v.required(d, "center", f"{where}."), f"{where}.center"), normal,
                  v.number(d.get("rotation_deg", 0.0), f"{where}.rotation_deg"), outer, inner, structure, table,
                  _flag(d, "top_surface", where, True), _flag(d, "dispersion", where, True))


def _structure_reference(value: Any, where: str, base_dir: Path | None) -> str:
    structure = str(value)
    if structure in BUILTIN_STRUCTURES:
        return structure
    path = (base_dir / structure) if base_dir is not None else Path(structure)
    if not path.exists():
        raise UserInputError("the structure file does not exist", field=where,
                             expected=f"a built-in structure ({', '.join(BUILTIN_STRUCTURES)}) or an existing TOML file",
                             got=structure)
    return str(path)


def _normal(value: Any, where: str) -> tuple[float, float, float]:
    normal = np.asarray(v.vector(value, where, 3))
    if np.linalg.norm(normal) == 0:
        raise UserInputError("the normal must not be zero", field=where, got=list(normal))
    return tuple(normal / np.linalg.norm(normal))


def _one_of(names) -> str:
    """``a, b, c or d``: a list of names as the error messages word it."""
    names = list(names)
    return ", ".join(names[:-1]) + f" or {names[-1]}" if len(names) > 1 else "".join(names)


TABLE_OPTIONS = {  # a scene's ``table = {...}``: the options of ``workbench rcwa table`` (rcwa.table.settings_for)
    "preset": "draft, paper or fine",
    "theta_step": "degrees, > 0", "phi_step": "degrees, > 0",
    "wavelengths": "'START:STOP:COUNT' in nm or 'NM,NM,...'",
    "orders": "retained harmonics: an odd integer N (1D) or [NX, NY] (2D)",
    "keep": "stored orders: an odd integer N (1D) or [NX, NY] (2D), at most `orders`",
    "pol": "unpolarized, s, p or all",
    "reflection_only": "true or false", "both_sides": "true or false", "use_symmetry": "true or false",
    "factorization": _one_of(FACTORIZATION_RULES),  # the registry's names: "auto, li, nv or laurent"
    "theta_range": "[LO, HI] in degrees", "phi_range": "[LO, HI] in degrees",
    "path": "a table built with `workbench rcwa table` (a .zarr folder)",
}
_TABLE_CHOICES = {"preset": ("draft", "paper", "fine"), "pol": ("unpolarized", "s", "p", "all"),
                  "factorization": tuple(FACTORIZATION_RULES)}


def _table_options(value: Any, where: str, base_dir: Path | None = None) -> dict:
    """A CD's or grating's ``table`` options, checked here so that a mistake names the scene
    file and field (``cd[0].table.orders``) rather than a command-line option. ``path``
    (relative to the scene file) names a finished table and stands alone."""
    if not isinstance(value, dict):
        raise UserInputError("must be a table of `workbench rcwa table` options", field=where,
                             expected="{ preset = \"draft\", orders = 31, ... }", got=value)
    for key, item in value.items():
        field_name = f"{where}.{key}"
        if key not in TABLE_OPTIONS:
            raise UserInputError("unknown table option", field=field_name, expected=f"one of {sorted(TABLE_OPTIONS)}")
        if key in _TABLE_CHOICES and item not in _TABLE_CHOICES[key]:
            raise UserInputError("unknown value", field=field_name, expected=TABLE_OPTIONS[key], got=item)
        if key in ("orders", "keep"):
            counts = item if isinstance(item, list) else [item]
            if not counts or any(isinstance(c, bool) or not isinstance(c, int) or c < 1 or c % 2 == 0 for c in counts):
                raise UserInputError("must be positive odd integers", field=field_name, expected=TABLE_OPTIONS[key], got=item)
        elif key in ("theta_step", "phi_step"):
            v.number(item, field_name, positive=True)
        elif key in ("reflection_only", "both_sides", "use_symmetry") and not isinstance(item, bool):
            raise UserInputError("must be true or false", field=field_name, got=item)
        elif key in ("theta_range", "phi_range"):
            v.vector(item, field_name, 2)
        elif key in ("wavelengths", "path") and not isinstance(item, str):
            raise UserInputError("must be a string", field=field_name, expected=TABLE_OPTIONS[key], got=item)
    options = dict(value)
    for key in ("orders", "keep"):
        if isinstance(options.get(key), list):
            options[key] = tuple(options[key])
    for key in ("theta_range", "phi_range"):
        if key in options:
            options[key] = tuple(float(x) for x in options[key])
    if "path" in options:
        if len(options) > 1:
            raise UserInputError("a table named by path is used as it is; the other options do not apply",
                                 field=where, expected='{ path = "..." } alone', got=sorted(options))
        path = Path(options["path"]).expanduser()
        options["path"] = str(base_dir / path if base_dir is not None else path)
    return options


def _parse_grating(d: Any, where: str, base_dir: Path | None) -> GratingSpec:
    if not isinstance(d, dict):
        raise UserInputError("must be a table", field=where, got=d)
    v.reject_unknown(d, {"center", "normal", "size", "rotation_deg", "structure", "table"}, f"{where}.")
    return GratingSpec(v.point(v.required(d, "center", f"{where}."), f"{where}.center"),
                       _normal(d.get("normal", [0.0, 0.0, -1.0]), f"{where}.normal"),
                       v.pair(v.required(d, "size", f"{where}."), f"{where}.size", positive=True),
                       v.number(d.get("rotation_deg", 0.0), f"{where}.rotation_deg"),
                       _structure_reference(v.required(d, "structure", f"{where}."), f"{where}.structure", base_dir),
                       _table_options(d.get("table", {"preset": "draft"}), f"{where}.table", base_dir))


def _parse_glass(d: Any, where: str) -> GlassSpec:
    if not isinstance(d, dict):
        raise UserInputError("must be a table", field=where, got=d)
    v.reject_unknown(d, {"shape", "center", "size", "radius", "rotation_deg", "material", "dispersion"}, f"{where}.")
    shape = d.get("shape", "cube")
    if shape not in ("cube", "sphere"):
        raise UserInputError("unknown glass shape", field=f"{where}.shape", expected='"cube" or "sphere"', got=shape)
    size_key = "size" if shape == "cube" else "radius"
    size = v.number(v.required(d, size_key, f"{where}."), f"{where}.{size_key}", positive=True)
    material = d.get("material", "n-bk7")
    try:
        material_from_spec(material)
    except UserInputError as exc:
        raise exc.located(field_prefix=f"{where}.material") from None
    return GlassSpec(shape, v.point(v.required(d, "center", f"{where}."), f"{where}.center"), size,
                     v.number(d.get("rotation_deg", 0.0), f"{where}.rotation_deg"), material,
                     _flag(d, "dispersion", where, True))


def _parse_camera(d: Any) -> CameraSpec:
    if not isinstance(d, dict):
        raise UserInputError("must be a table", field="camera", got=d)
    v.reject_unknown(d, {"resolution", "look_at", "world_to_camera", "fov_deg", "focal_mm", "focal_px", "sensor_mm",
                         "principal_offset_px", "dist", "model", "xi", "exposure", "sensitivities", "response"}, "camera.")
    w, h = (int(x) for x in v.vector(v.required(d, "resolution", "camera."), "camera.resolution", 2, positive=True))
    focal_px = v.vector(d["focal_px"], "camera.focal_px", 2, positive=True) if "focal_px" in d else None
    if focal_px is not None and ("fov_deg" in d or "focal_mm" in d):
        raise UserInputError("give one of fov_deg, focal_mm or focal_px", field="camera.focal_px")
    if "world_to_camera" in d:  # an explicit pose, as calibration writes it (fitted_scene.toml)
        if "look_at" in d:
            raise UserInputError("give look_at or world_to_camera, not both", field="camera.world_to_camera")
        pose = _rigid_transform(d["world_to_camera"], "camera.world_to_camera")
    else:
        pose = _look_at_pose(v.required(d, "look_at", "camera."))
    if focal_px is not None:
        fov = 2 * math.degrees(math.atan(0.5 * w / focal_px[0]))
    elif "fov_deg" in d:
        fov = v.number(d["fov_deg"], "camera.fov_deg", positive=True)
    elif "focal_mm" in d:
        focal = v.number(d["focal_mm"], "camera.focal_mm", positive=True)
        sensor = v.vector(v.required(d, "sensor_mm", "camera."), "camera.sensor_mm", 2, positive=True)
        fov = 2 * math.degrees(math.atan(0.5 * sensor[0] / focal))
    else:
        raise UserInputError("is missing", field="camera.fov_deg", expected="fov_deg, or focal_mm with sensor_mm")
    if not fov < 180:
        raise UserInputError("the field of view must be under 180 degrees", field="camera.fov_deg", got=fov)
    lens_name, xi = str(d.get("model", "pinhole")), v.number(d.get("xi", 0.0), "camera.xi")
    if lens_name not in LENS_MODELS:
        raise UserInputError("unknown lens model", field="camera.model", expected=f"one of {', '.join(LENS_MODELS)}",
                             got=lens_name)
    count = LENS_MODELS[lens_name].count
    dist = v.vector(d.get("dist", [0.0] * count), "camera.dist", count)
    if lens_name != "omnidir" and xi != 0.0:
        raise UserInputError(f"is a parameter of the omnidir model, not of {lens_name}", field="camera.xi")
    offset = v.vector(d.get("principal_offset_px", [0.0, 0.0]), "camera.principal_offset_px", 2)
    sens = str(d.get("sensitivities", "Nikon 5100 (NPL)"))
    import colour  # deferred: start-up time

    if sens not in colour.MSDS_CAMERA_SENSITIVITIES:
        raise UserInputError("unknown camera sensitivities", field="camera.sensitivities",
                             expected=f"one of {sorted(colour.MSDS_CAMERA_SENSITIVITIES)}", got=sens)
    model = CameraModel.from_fov(w, h, fov, pose, dist, offset, lens_name, xi)
    if focal_px is not None:
        model = replace(model, fx=focal_px[0], fy=focal_px[1])
    return CameraSpec(model, v.number(d.get("exposure", 1.0), "camera.exposure", positive=True), sens,
                      ResponseCurve.from_spec(d.get("response", "linear")))


def _look_at_pose(la: Any) -> np.ndarray:
    if not isinstance(la, dict):
        raise UserInputError("must be a table {origin, target, up}", field="camera.look_at", got=la)
    origin = v.vector(v.required(la, "origin", "camera.look_at."), "camera.look_at.origin", 3)
    target = v.vector(v.required(la, "target", "camera.look_at."), "camera.look_at.target", 3)
    up = v.vector(la.get("up", [0.0, 1.0, 0.0]), "camera.look_at.up", 3)
    try:
        return look_at(origin, target, up)
    except ValueError as exc:
        raise UserInputError(str(exc), field="camera.look_at") from None


def _rigid_transform(value: Any, where: str) -> np.ndarray:
    """A 4 x 4 world-to-camera matrix (OpenCV axes, metres): a rotation (orthonormal to 1e-6,
    determinant +1), a translation, and the last row 0, 0, 0, 1."""
    if not isinstance(value, list) or len(value) != 4:
        raise UserInputError("must be 4 rows of 4 numbers", field=where, got=value)
    T = np.array([v.vector(row, f"{where}[{i}]", 4) for i, row in enumerate(value)])
    R = T[:3, :3]
    if not (np.allclose(R @ R.T, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0 and np.allclose(T[3], [0, 0, 0, 1])):
        raise UserInputError("is not a rigid transform", field=where,
                             expected="a rotation (orthonormal, determinant +1), a translation, last row [0, 0, 0, 1]")
    return T


def _measured_bounds() -> tuple[np.ndarray, np.ndarray]:
    pts = np.concatenate([np.asarray(q, dtype=float) for k, q in cornell_data()["geometry"].items()
                          if k.endswith(("_white", "_green", "_red")) and "block" not in k]) * MM
    return pts.min(axis=0), pts.max(axis=0)


def box_scale(box: dict) -> np.ndarray:
    """Per-axis factor from the measured box to the scene's (``box.size``)."""
    lo, hi = _measured_bounds()
    return np.asarray(box["size"]) / (hi - lo) if "size" in box else np.ones(3)


def _box_bounds(box: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = _measured_bounds()
    scale = box_scale(box or {})
    return lo * scale, hi * scale


# Scene sanity (docs/scene_format.md, "Placement checks"): what would render black or miss the scene is refused.
SLACK_M = 1e-3            # an object may touch a wall (a CD resting on the floor, round-off), not pass through it
LIGHT_DROP = 0.02         # of the box's height: how far below the ceiling the ceiling light may hang (measured: 0.1 mm)


def _extent(lo: np.ndarray, hi: np.ndarray) -> str:
    return "the box's extent, " + ", ".join(f"{a} {a0:.4g} to {a1:.4g}" for a, a0, a1 in zip("xyz", lo, hi, strict=True)) + " m"


def _check_placement(box: dict, light: LightSpec, cds, gratings, glass, camera: CameraModel, pose_field: str) -> tuple[str, ...]:
    """The light in the ceiling, every object in the box, each CD and opaque grating lit on its front,
    the camera in the box or before its open front looking in. Returns the warnings (a camera that sees little)."""
    lo, hi = _box_bounds(box)
    _check_light_placement(light, lo, hi)
    for i, cd in enumerate(cds):
        top = np.asarray(cd.center) + (CD_TOP_THICKNESS_M if cd.top_surface else 0.0) * np.asarray(cd.normal)
        _check_inside(np.stack([cd.center, top]), _disc_half_extent(cd.outer_radius, cd.normal), f"cd[{i}]", lo, hi)
        if not _lit_front(cd.center, cd.normal, light):
            _refuse_unlit(cd.normal, f"cd[{i}]")
    for i, g in enumerate(gratings):  # the disc inscribed in the plate: any rotation of it lies inside it
        _check_inside(np.asarray([g.center]), _disc_half_extent(min(g.size) / 2, g.normal), f"grating[{i}]", lo, hi)
        if not _lit_front(g.center, g.normal, light) and not _transmits(g.structure):  # see-through: lit from behind,
            _refuse_unlit(g.normal, f"grating[{i}]")                                   # it shows its transmitted orders
    for i, item in enumerate(glass):
        turn = math.radians(item.rotation_deg)  # a cube turns about y
        across = abs(math.cos(turn)) + abs(math.sin(turn))
        half = np.full(3, item.size) if item.shape == "sphere" else item.size / 2 * np.array([across, 1.0, across])
        _check_inside(np.asarray([item.center]), half, f"glass[{i}]", lo, hi)
    share = check_camera_placement(camera, lo, hi, pose_field)
    return camera_view_warnings(camera, [e.center for e in (*cds, *gratings)], share)


def _check_light_placement(light: LightSpec, lo: np.ndarray, hi: np.ndarray) -> None:
    """The ceiling light: its rectangle in the ceiling's plane (at most LIGHT_DROP of the box's height below
    it, never above it: the ceiling would hide it) and within the ceiling's x, z extent."""
    x, y, z = light.center
    half = np.asarray(light.size) / 2
    if np.any(2 * half > hi[[0, 2]] - lo[[0, 2]] + SLACK_M):
        raise UserInputError("the light is larger than the box's ceiling", field="light.size",
                             expected=f"at most {hi[0] - lo[0]:.4g} x {hi[2] - lo[2]:.4g} m", got=list(light.size))
    floor_y = hi[1] - LIGHT_DROP * (hi[1] - lo[1])
    on_ceiling = floor_y <= y <= hi[1] + 1e-9
    within = np.all(np.abs([x, z] - (lo[[0, 2]] + hi[[0, 2]]) / 2) + half <= (hi[[0, 2]] - lo[[0, 2]]) / 2 + SLACK_M)
    if not (on_ceiling and within):
        raise UserInputError(
            "the light is not in the box's ceiling", field="light.center",
            expected=f"y {floor_y:.4g} to {hi[1]:.4g} m (the ceiling) and its {2 * half[0]:.4g} x {2 * half[1]:.4g} m "
                     f"rectangle within the ceiling's x and z ({_extent(lo, hi)})",
            got=[round(c, 4) for c in light.center])


def _disc_half_extent(radius: float, normal) -> np.ndarray:
    """Half the extent along x, y, z of a disc of ``radius`` about ``normal``."""
    return radius * np.sqrt(np.clip(1.0 - np.square(np.asarray(normal, float)), 0.0, None))


def _check_inside(centers: np.ndarray, half: np.ndarray, where: str, lo: np.ndarray, hi: np.ndarray) -> None:
    """An object (its centres ``centers``, each +- ``half`` along x, y, z) inside the box, SLACK_M allowed."""
    if np.all(centers - half >= lo - SLACK_M) and np.all(centers + half <= hi + SLACK_M):
        return
    raise UserInputError(f"{where} is outside the box or through a wall", field=f"{where}.center",
                         expected=f"the object (+- {np.round(half, 4).tolist()} m about its centre) within {_extent(lo, hi)}",
                         got=np.round(centers[0], 4).tolist())


def _transmits(structure: str) -> bool:
    """A see-through structure (a lossless substrate), as renderer.tables.table_settings decides."""
    eps = np.asarray(load_structure(structure).substrate.epsilon(np.array([550.0])))
    return bool(np.all((eps.imag == 0) & (eps.real > 0)))


def _lit_front(center, normal, light: LightSpec) -> bool:
    """Some point of the light (a corner of its rectangle) in front of the element's plane: else no light
    reaches its grooved side and it renders black (a flat element's plane is the same for all its points)."""
    corners = np.array([[light.center[0] + sx * light.size[0] / 2, light.center[1], light.center[2] + sz * light.size[1] / 2]
                        for sx in (-1, 1) for sz in (-1, 1)])
    return bool(np.max((corners - np.asarray(center)) @ np.asarray(normal)) > 0)


def _refuse_unlit(normal, where: str) -> None:
    raise UserInputError(f"{where} faces away from the light: no light reaches its front (the grooved side)",
                         field=f"{where}.normal", expected="a normal with part of the light in front of it, "
                         "(light point - center) . normal > 0", got=np.round(normal, 4).tolist())

"""Periodic multilayer structures and their TOML file format (docs/structure_format.md).

A structure is a period (``[Lx]`` for 1D gratings with grooves along y, ``[Lx, Ly]`` for
2D), a superstrate, a substrate and a list of layers from the superstrate down. Each layer
has a thickness, a background material and shapes painted over it (later shapes overwrite
earlier ones). Lengths are micrometres. Every error names the file and the field.
"""

from __future__ import annotations

import hashlib
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import tomli_w
from shapely.geometry import Polygon as ShapelyPolygon

from rcwa.materials import Material, material_from_spec
from rcwa.shapes import Circle, Polygon, Rect, Shape, Shape2D, Stripe
from workbench.core import validation
from workbench.core.errors import UserInputError

BUILTIN_STRUCTURES: tuple[str, ...] = ("cd", "gold2d")

_TOP_KEYS = {"name", "description", "period", "superstrate", "substrate", "layers", "notes"}
_LAYER_KEYS = {"thickness", "material", "shapes", "name"}
MAX_LAYERS = 1000  # issue 46, cause 1: a structure of 100,000 layers ran until time ran out


@dataclass(frozen=True)
class Layer:
    thickness: float
    material: Material
    shapes: tuple[Shape, ...] = ()
    name: str = ""

    @property
    def is_uniform(self) -> bool:
        return not self.shapes

    @property
    def shapes_2d(self) -> tuple[Shape2D, ...]:
        """The shapes of a layer in a 2D cell (the parser admits no stripes there)."""
        shapes = tuple(s for s in self.shapes if not isinstance(s, Stripe))
        if len(shapes) != len(self.shapes):
            raise ValueError("a layer of a 2D cell holds a 1D stripe")
        return shapes


@dataclass(frozen=True)
class Structure:
    """A parsed, validated structure. ``source`` names where it came from."""

    name: str
    period: tuple[float, ...]
    superstrate: Material
    substrate: Material
    layers: tuple[Layer, ...]
    source: str = "<structure>"
    text: str = field(default="", repr=False, compare=False)

    @property
    def dimension(self) -> int:
        return len(self.period)

    @property
    def content_hash(self) -> str:
        """SHA-256 of the file's text (the key of cached tables)."""
        return hashlib.sha256(self.text.encode()).hexdigest()

    def field_of(self, material: Material) -> str:
        """The dotted field path where ``material`` is used first (for error messages)."""
        if material is self.superstrate:
            return "superstrate"
        if material is self.substrate:
            return "substrate"
        for i, layer in enumerate(self.layers):
            if material is layer.material:
                return f"layers[{i}].material"
            for j, shape in enumerate(layer.shapes):
                if material is shape.material:
                    return f"layers[{i}].shapes[{j}].material"
        return "material"

    @classmethod
    def from_toml(cls, path: str | Path) -> "Structure":
        path = Path(path)
        text = validation.read_text_file(path, "structure")
        return cls.from_toml_string(text, source=str(path), base_dir=path.parent)

    @classmethod
    def from_toml_string(cls, text: str, *, source: str = "<string>", base_dir: Path | None = None) -> "Structure":
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise UserInputError(f"not valid TOML ({exc})", file=source) from None
        except RecursionError:  # tomllib parses nested arrays recursively
            raise UserInputError("not valid TOML (arrays or tables nested too deeply)", file=source) from None
        return cls.from_dict(data, source=source, base_dir=base_dir, text=text)

    @classmethod
    def from_dict(
        cls, data: dict[str, Any], *, source: str = "<dict>", base_dir: Path | None = None, text: str | None = None
    ) -> "Structure":
        if text is None:
            # The same structure as TOML, so that tables can store and re-read it.
            try:
                text = tomli_w.dumps(data)
            except (TypeError, ValueError):
                text = repr(data)  # not TOML-serializable; _parse reports what is wrong
        try:
            return _parse(data, source, base_dir, text)
        except UserInputError as exc:
            raise exc.located(file=source) from None


def load_structure(name_or_path: str | Path) -> Structure:
    """A built-in structure by name (``cd``, ``gold2d``) or a TOML file by path."""
    name = str(name_or_path)
    if name in BUILTIN_STRUCTURES:
        resource = resources.files("rcwa.structures").joinpath(f"{name}.toml")
        return Structure.from_toml_string(resource.read_text(), source=f"<built-in {name}>")
    path = Path(name)
    if not path.exists() and not validation.looks_like_path(name):
        raise UserInputError(
            "no such structure",
            field="structure",
            expected=f"a built-in name ({', '.join(BUILTIN_STRUCTURES)}) or a TOML file",
            got=name,
        )
    return Structure.from_toml(path)


# ---------------------------------------------------------------- parsing


def _parse(data: dict[str, Any], source: str, base_dir: Path | None, text: str) -> Structure:
    if not isinstance(data, dict):
        raise UserInputError("the structure must be a table", expected="a TOML table", got=type(data).__name__)
    _reject_unknown(data, _TOP_KEYS, "")
    period = _parse_period(data.get("period"))
    material = _material_parser(base_dir)
    superstrate = material(_required(data, "superstrate", ""), "superstrate")
    substrate = material(_required(data, "substrate", ""), "substrate")
    layers_data = data.get("layers", [])
    if not isinstance(layers_data, list):
        raise UserInputError("must be a list of tables ([[layers]])", field="layers", got=layers_data)
    if len(layers_data) > MAX_LAYERS:  # every layer is an eigen-solve per direction: refused before any
        raise UserInputError(f"has {len(layers_data)} layers, more than the {MAX_LAYERS} a structure may have",
                             field="layers", expected=f"at most {MAX_LAYERS} layers (a staircase of a smooth profile "
                                                      "needs tens; uniform layers of one material can be merged)")
    layers = tuple(_parse_layer(item, f"layers[{i}]", period, material) for i, item in enumerate(layers_data))
    name = data.get("name", Path(source).stem if not source.startswith("<") else "structure")
    if not isinstance(name, str):
        raise UserInputError("must be a string", field="name", got=name)
    return Structure(name, period, superstrate, substrate, layers, source=source, text=text)


_required = validation.required
_reject_unknown = validation.reject_unknown
_number = validation.number
_pair = validation.pair


def _parse_period(value: Any) -> tuple[float, ...]:
    if value is None:
        raise UserInputError("is missing", field="period", expected="[Lx] (1D) or [Lx, Ly] (2D) in micrometres")
    if not isinstance(value, list) or len(value) not in (1, 2):
        raise UserInputError("must be a list of one or two lengths", field="period", expected="[Lx] or [Lx, Ly]", got=value)
    return tuple(_number(v, f"period[{i}]", positive=True) for i, v in enumerate(value))


def _material_parser(base_dir: Path | None):
    def parse(spec: Any, where: str) -> Material:
        try:
            return material_from_spec(spec, base_dir=base_dir)
        except UserInputError as exc:
            raise exc.located(field_prefix=where) from None

    return parse


def _parse_layer(item: Any, where: str, period: tuple[float, ...], material) -> Layer:
    if not isinstance(item, dict):
        raise UserInputError("must be a table", field=where, got=item)
    _reject_unknown(item, _LAYER_KEYS, f"{where}.")
    thickness = _number(_required(item, "thickness", f"{where}."), f"{where}.thickness", nonnegative=True)
    background = material(_required(item, "material", f"{where}."), f"{where}.material")
    shapes_data = item.get("shapes", [])
    if not isinstance(shapes_data, list):
        raise UserInputError("must be a list of shape tables", field=f"{where}.shapes", got=shapes_data)
    shapes = tuple(
        _parse_shape(s, f"{where}.shapes[{j}]", period, material) for j, s in enumerate(shapes_data)
    )
    name = item.get("name", "")
    return Layer(thickness, background, shapes, str(name))


def _parse_shape(item: Any, where: str, period: tuple[float, ...], material) -> Shape:
    if not isinstance(item, dict):
        raise UserInputError("must be a table", field=where, got=item)
    kinds = [k for k in ("x", "rect", "circle", "polygon") if k in item]
    _reject_unknown(item, {"material", "x", "rect", "circle", "polygon", "name"}, f"{where}.")
    if len(kinds) != 1:
        raise UserInputError(
            "must have exactly one geometry",
            field=where,
            expected="one of x (1D stripe), rect, circle, polygon",
            got=sorted(item),
        )
    kind = kinds[0]
    mat = material(_required(item, "material", f"{where}."), f"{where}.material")
    if len(period) == 1:
        if kind != "x":
            raise UserInputError(
                "a 1D structure (period = [Lx]) takes stripes only", field=f"{where}.{kind}", expected="x = [x0, x1]"
            )
        return _parse_stripe(item["x"], f"{where}.x", period[0], mat)
    if kind == "x":
        raise UserInputError("a 2D structure (period = [Lx, Ly]) takes rect, circle or polygon", field=f"{where}.x")
    shape = _parse_2d(kind, item[kind], f"{where}.{kind}", mat)
    _check_fits_period(shape, period, f"{where}.{kind}")
    return shape


def _check_fits_period(shape: Shape2D, period: tuple[float, ...], where: str) -> None:
    """A 2D shape wider than the cell would overlap its own periodic image."""
    minx, miny, maxx, maxy = shape.outline().bounds
    if maxx - minx > period[0] * (1 + 1e-12) or maxy - miny > period[1] * (1 + 1e-12):
        raise UserInputError(
            "the shape is larger than the unit cell (it would overlap its own periodic image)",
            field=where, expected=f"a width <= {period[0]} and a height <= {period[1]}",
            got=[round(maxx - minx, 12), round(maxy - miny, 12)],
        )


def _parse_stripe(value: Any, where: str, period: float, mat: Material) -> Stripe:
    x0, x1 = _pair(value, where)
    if not x1 > x0:
        raise UserInputError("the stripe must end after it starts", field=where, expected="x1 > x0", got=value)
    if x1 - x0 > period * (1 + 1e-12):
        raise UserInputError("the stripe is wider than the period", field=where, expected=f"x1 - x0 <= {period}", got=value)
    return Stripe(mat, x0, x1)


def _parse_2d(kind: str, value: Any, where: str, mat: Material) -> Shape2D:
    if kind == "polygon":
        if not isinstance(value, list) or len(value) < 3:
            raise UserInputError("must list at least 3 vertices", field=where, expected="[[x, y], ...]", got=value)
        vertices = tuple(_pair(v, f"{where}[{i}]") for i, v in enumerate(value))
        outline = ShapelyPolygon(vertices)
        if not outline.is_valid or outline.area <= 0:
            raise UserInputError("the polygon must be simple (no self-crossing) with non-zero area", field=where, got=value)
        return Polygon(mat, vertices)
    if not isinstance(value, dict):
        raise UserInputError("must be a table", field=where, got=value)
    if kind == "rect":
        _reject_unknown(value, {"center", "size"}, f"{where}.")
        center = _pair(_required(value, "center", f"{where}."), f"{where}.center")
        size = _pair(_required(value, "size", f"{where}."), f"{where}.size")
        if not (size[0] > 0 and size[1] > 0):
            raise UserInputError("sizes must be positive", field=f"{where}.size", got=list(size))
        return Rect(mat, center, size)
    _reject_unknown(value, {"center", "radius"}, f"{where}.")
    center = _pair(_required(value, "center", f"{where}."), f"{where}.center")
    radius = _number(_required(value, "radius", f"{where}."), f"{where}.radius", positive=True)
    return Circle(mat, center, radius)

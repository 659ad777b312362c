"""A scene's free parameters for scene fitting: the ``[fit]`` table (docs/scene_format.md).

Each key of ``[fit]`` names a field of the scene file, in the file's own words, and its
value is a table of options (``{}`` takes the defaults)::

    [fit]
    "cd[0].structure.period" = { bounds = [1.5, 1.7] }   # um, the structure file's unit
    "cd[0].normal" = { within_deg = 5.0 }                 # tilt, degrees from the file's normal
    "light.center" = { within = 0.10, prior_std = 0.05 }  # metres; x and z (the light is in the ceiling)

Options: ``bounds`` ([lo, hi], or one [lo, hi] per component), ``within`` (+- about the
file's value, in the field's unit; ``within_deg`` for a normal, and only there; bounds or
within, not both), ``prior_std`` (a Gaussian prior about the file's value: one number or
one per component). The fit varies each parameter in *fit coordinates*
(``FitParameter.components``):

==================================  ==========================  =========================================
name                                components                  unit
==================================  ==========================  =========================================
``cd[i].structure.period``          the period                  um
``cd[i].structure.layers[j].thickness``  the layer's thickness  um (read from the structure; see below)
``cd[i].structure.layers[j].shapes[k].width``  the stripe's width  um, about the stripe's centre (the groove's width)
``cd[i].center``                    x, y, z                     m
``cd[i].normal``                    tilt toward e1, toward e2   deg (e1, e2: the CD's frame, placement.frame_to)
``light.center``                    x, z                        m (y is the ceiling's)
``light.size``                      x, z                        m
``light.power_w``                   held                        W: photos fix only exposure x power
==================================  ==========================  =========================================

``cd[i].rotation_deg`` is refused: a CD's tracks are circles about its centre, so its
rotation changes nothing the photos show. ``light.power_w`` is accepted and held (listed
in the fit's ``held`` with the reason): one exposure cannot separate the light's power from
the camera's exposure, and calibration already fits their product (its photometric scale).
A scene without ``[fit]`` that has a CD takes :data:`DEFAULT_FREE` for its first CD.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from rcwa.shapes import Stripe
from rcwa.structure import load_structure
from workbench.core.errors import UserInputError

DEFAULT_FREE = ("cd[0].structure.period", "cd[0].normal", "light.center")
HELD = {"light.power_w": "one photo's brightness fixes only exposure x light power; calibration fits that product "
                         "(its photometric scale), so the power is held at the scene file's value"}
DEFAULT_WITHIN = {"structure.period": ("relative", 0.10), "thickness": ("relative", 0.3), "width": ("relative", 0.3),
                  "center": ("absolute", 0.03),
                  "normal": ("absolute", 10.0), "light.center": ("absolute", 0.15), "light.size": ("relative", 0.6)}
_CD_NAME = re.compile(r"^cd\[(\d+)\]\.(center|normal|rotation_deg|structure\.period"
                      r"|structure\.layers\[(\d+)\]\.(?:thickness|shapes\[(\d+)\]\.width))$")
_OPTIONS = {"bounds", "within", "within_deg", "prior_std"}


@dataclass(frozen=True)
class FitParameter:
    """One free field of the scene, in fit coordinates (module docstring)."""

    name: str
    kind: str  # "period", "thickness", "width", "center", "normal", "light.center", "light.size"
    cd_index: int | None
    components: tuple[str, ...]
    unit: str
    nominal: tuple[float, ...]  # the scene file's value in fit coordinates (a normal's tilts: 0, 0)
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    prior_std: tuple[float, ...] | None = None
    layer: int | None = None  # the structure's layer (thickness, width)
    shape: int | None = None  # the layer's stripe (width)

    @property
    def size(self) -> int:
        return len(self.components)


@dataclass(frozen=True)
class FitTable:
    """The parsed ``[fit]`` table: the free parameters and the held ones with the reason."""

    free: tuple[FitParameter, ...]
    held: dict[str, str]
    declared: bool  # False: the defaults (the scene has no [fit])

    @property
    def size(self) -> int:
        return sum(p.size for p in self.free)

    def nominal(self) -> np.ndarray:
        return np.concatenate([p.nominal for p in self.free]) if self.free else np.zeros(0)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.concatenate([p.lower for p in self.free]), np.concatenate([p.upper for p in self.free]))

    def labels(self) -> list[str]:
        return [f"{p.name}:{c}" for p in self.free for c in p.components]

    def split(self, values: np.ndarray) -> dict[str, np.ndarray]:
        """{name: its components} from one flat vector in fit coordinates."""
        out, at = {}, 0
        for p in self.free:
            out[p.name] = np.asarray(values[at:at + p.size], float)
            at += p.size
        return out


def parse_fit_table(value: Any, cds: tuple, light: Any) -> FitTable:
    """The ``[fit]`` table against the scene's CDs and light (``value`` None: the defaults)."""
    if value is None:
        if not cds:
            return FitTable((), {}, False)
        return FitTable(tuple(p for p in (_default(name, cds, light) for name in DEFAULT_FREE) if p is not None), {}, False)
    if not isinstance(value, dict):
        raise UserInputError("must be a table of parameter names", field="fit",
                             expected='e.g. [fit] "cd[0].structure.period" = { bounds = [1.5, 1.7] }', got=value)
    free, held = [], {}
    for name, options in value.items():
        if not isinstance(options, dict):
            raise UserInputError("must be a table of options (bounds, within, prior_std; {} for the defaults)",
                                 field=f"fit.{name}", got=options)
        if name in HELD:
            held[name] = HELD[name]
            continue
        free.append(_parameter(name, options, cds, light))
    return FitTable(tuple(free), held, True)


def _default(name: str, cds: tuple, light: Any) -> FitParameter | None:
    """A default parameter, or None where the scene's CD has no such field (a 2D structure has no
    single period: the scene loads, and its fit leaves the period out)."""
    try:
        return _parameter(name, {}, cds, light)
    except UserInputError:
        return None


def _parameter(name: str, options: dict, cds: tuple, light: Any) -> FitParameter:
    where = f"fit.{name}"
    unknown = set(options) - _OPTIONS
    if unknown:
        raise UserInputError(f"unknown option {sorted(unknown)[0]!r}", field=where, expected=", ".join(sorted(_OPTIONS)))
    if name in ("light.center", "light.size"):
        nominal = (light.center[0], light.center[2]) if name == "light.center" else tuple(light.size)
        return _with_options(FitParameter(name, name, None, ("x", "z"), "m", tuple(map(float, nominal)), (), ()), options)
    match = _CD_NAME.match(name)
    if not match:
        raise UserInputError("names no field the scene fit can vary", field=where,
                             expected="cd[i].structure.period, cd[i].structure.layers[j].thickness, "
                                      "cd[i].structure.layers[j].shapes[k].width, cd[i].center, cd[i].normal, "
                                      "light.center, light.size or light.power_w")
    index = int(match.group(1))
    if index >= len(cds):
        raise UserInputError(f"the scene has {len(cds)} CD(s): no cd[{index}]", field=where)
    field = match.group(2)
    cd = cds[index]
    if field == "rotation_deg":
        raise UserInputError("a CD's tracks are circles about its centre: its rotation changes nothing the photos show "
                             "(not identifiable); leave it out of [fit]", field=where)
    if field == "center":
        return _with_options(FitParameter(name, "center", index, ("x", "y", "z"), "m", tuple(cd.center), (), ()), options)
    if field == "normal":
        return _with_options(FitParameter(name, "normal", index, ("tilt_e1", "tilt_e2"), "deg", (0.0, 0.0), (), ()),
                             options)
    structure = load_structure(cd.structure)
    if field == "structure.period":
        if len(structure.period) != 1:
            raise UserInputError("the CD's structure has no single period (a CD's grating is 1D)", field=where,
                                 got=f"{cd.structure}: period {list(structure.period)}")
        return _with_options(FitParameter(name, "period", index, ("value",), "um", (float(structure.period[0]),), (), ()),
                             options)
    layer = int(match.group(3))
    if layer >= len(structure.layers):
        raise UserInputError(f"the CD's structure has {len(structure.layers)} layer(s): no layers[{layer}]", field=where,
                             got=cd.structure)
    if match.group(4) is None:
        return _with_options(FitParameter(name, "thickness", index, ("value",), "um",
                                          (float(structure.layers[layer].thickness),), (), (), layer=layer), options)
    shape, shapes = int(match.group(4)), structure.layers[layer].shapes
    stripe = shapes[shape] if shape < len(shapes) else None
    if not isinstance(stripe, Stripe):
        raise UserInputError(f"layers[{layer}] of the CD's structure has no stripe shapes[{shape}]", field=where,
                             got=f"{cd.structure}: {len(shapes)} shape(s)")
    width = _with_options(FitParameter(name, "width", index, ("value",), "um", (float(stripe.x1 - stripe.x0),), (), (),
                                       layer=layer, shape=shape), options)
    if width.upper[0] > structure.period[0]:
        raise UserInputError("the stripe cannot be wider than the period", field=f"{where}.bounds",
                             expected=f"at most {structure.period[0]} um", got=list(width.upper))
    return width


def _per_component(value: Any, size: int, where: str) -> tuple[float, ...]:
    values = [value] * size if isinstance(value, (int, float)) and not isinstance(value, bool) else value
    if not isinstance(values, list) or len(values) != size or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in values):
        raise UserInputError(f"must be a number or {size} numbers", field=where, got=value)
    return tuple(float(x) for x in values)


def _with_options(p: FitParameter, options: dict) -> FitParameter:
    where = f"fit.{p.name}"
    nominal = np.asarray(p.nominal)
    key = "within_deg" if p.kind == "normal" else "within"
    wrong = "within" if key == "within_deg" else "within_deg"
    if wrong in options:  # would be ignored: a normal's half-width is in degrees, every other one in the field's unit
        raise UserInputError(f"is not an option of {p.name}", field=f"{where}.{wrong}", expected=f"{key} ({p.unit})")
    if "bounds" in options and key in options:
        raise UserInputError(f"give bounds or {key}, not both", field=where, got=sorted(options))
    if "bounds" in options:
        lower, upper = _bounds(options["bounds"], p.size, f"{where}.bounds")
    else:
        kind, default = DEFAULT_WITHIN["structure.period" if p.kind == "period" else p.kind]
        half = np.asarray(_per_component(options.get(key, default), p.size, f"{where}.{key}"))
        if np.any(half <= 0):
            raise UserInputError("must be positive", field=f"{where}.{key}", got=options.get(key))
        half = half * np.abs(nominal) if kind == "relative" and key not in options else half
        lower, upper = nominal - half, nominal + half
    if np.any(lower >= upper) or np.any(nominal < lower) or np.any(nominal > upper):
        raise UserInputError("the bounds must contain the scene file's value", field=f"{where}.bounds",
                             expected=f"lo < {list(map(float, nominal))} < hi per component",
                             got=[list(x) for x in zip(lower.tolist(), upper.tolist(), strict=True)])
    if p.kind in ("period", "thickness", "width", "light.size") and np.any(lower <= 0):
        raise UserInputError("must stay positive", field=f"{where}.bounds", got=lower.tolist())
    prior = None
    if "prior_std" in options:
        prior = _per_component(options["prior_std"], p.size, f"{where}.prior_std")
        if any(s <= 0 for s in prior):
            raise UserInputError("must be positive", field=f"{where}.prior_std", got=options["prior_std"])
    return replace(p, lower=tuple(lower.tolist()), upper=tuple(upper.tolist()), prior_std=prior)


def _bounds(value: Any, size: int, where: str) -> tuple[np.ndarray, np.ndarray]:
    rows = [value] if size == 1 and isinstance(value, list) and len(value) == 2 and not isinstance(value[0], list) else value
    if not isinstance(rows, list) or len(rows) != size or not all(isinstance(r, list) and len(r) == 2 for r in rows):
        raise UserInputError(f"must be [lo, hi]{'' if size == 1 else f' for each of {size} components'}", field=where,
                             got=value)
    pairs = [_per_component(r, 2, where) for r in rows]
    return np.array([a for a, _ in pairs]), np.array([b for _, b in pairs])

"""The BWDF: a grating's diffraction orders as a Mitsuba 3 BSDF plugin (``type = "bwdf"``).

The parameters, their defaults and a usage example are in :class:`GratingBWDF`'s
docstring; this one states the physics.

Modes. ``"paper"`` reproduces [Lange 2021, Eqs. 2-5]: one of the N_tot kept orders
chosen uniformly, one of the ray's wavelengths at random (the hero), the incident
direction from Eqs. 2-3, the Delta test (Eqs. 4-5) for the other wavelengths, each read at
its own implied order, and the weight DE * N_tot / cos(theta_o) times pbrt's
|cos(theta_i)| (pbrt-v3's f * |cos| / pdf, [Pharr 2016]). ``"improved"`` is hero-wavelength
MIS [Wilkie 2014] for delta lobes: the specular order, whose direction is the same at
every wavelength, is chosen with the mean of its efficiency over the ray's wavelengths and
keeps all of them (weight DE_i(0) / q0 each); otherwise a diffracted order is chosen at the
hero wavelength (by efficiency, mixed with a uniform share) and the other wavelengths are
terminated, the hero reweighted by their number (pbrt-v4's TerminateSecondary, the limit
of that MIS when the directions differ).

Weights, and where paper mode differs. Mitsuba's ``sample`` returns f |cos| / pdf. A
grating order maps direction cosines (times the medium's index) by a translation, which
preserves projected solid angle, so a radiance L_i arriving along the order's incident
direction leaves as DE * L_i: improved mode's weight per chosen order is DE / p(order).
The paper's pbrt-v3 weight carries an extra cos(theta_i)/cos(theta_o); paper mode keeps
it, as written, so the two can be compared (the accuracy-vs-time study reports the
difference).

See-through elements (tables built with ``--both-sides`` and a transmitting substrate):
two components, reflection (0) and transmission (1), for a camera above (superstrate
side) or below: reflection from the camera's side and transmission from the other (R,
T_below above; R_below, T below). The grating equation keeps the tangential wave vector
across two indices, and a transmitted radiance scales by (n_c / n_l)^2 (the n^2 law of
radiance; [Veach 1997, Sec. 5.2]) in radiance transport only; importance (adjoint)
transport carries no such factor, as Mitsuba's ``dielectric``. Improved mode samples the
orders of every enabled component by efficiency; paper mode tosses a fair coin between
reflection and transmission (weight x2), as the paper's Sec. 2.2 does. A component that
the BSDFContext disables is never sampled: the choice runs over the enabled ones only.

Directions (Mitsuba's si.wi is the paper's omega_o, toward the camera; bs.wo is its
omega_i, toward the light). Tangential wave vectors are divided by k0 = 2 pi / lambda. The
camera's order travels along omega_o (tangential k_o = n_c omega_o,t); the incident wave
travels along -omega_i (k_inc = -n_l omega_i,t). Order (m, n) links them by Eq. 2 with the
sign of workbench.core.conventions (ORDER_SIGN, the one place it is stated):
    k_o = k_inc + ORDER_SIGN * (m lambda / Lambda_x, n lambda / Lambda_y),
and the table is read at the incident wave's (theta, phi): theta of omega_i and the
azimuth of -omega_i,t.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from rcwa.structure import Structure
from rcwa.table import open_table
from renderer.delta_lobes import (
    WAVELENGTHS_PER_RAY,
    DeltaLobesBSDF,
    choose_hero,
    select,
)
from renderer.efficiency import EfficiencyLookup
from renderer.variant import check_variant
from workbench.core.conventions import ORDER_SIGN

MODES = ("paper", "improved")
MAPPINGS = ("constant", "radial")
REFLECTION, TRANSMISSION = 0, 1  # component indices (BSDFContext.component, bs.sampled_component)
DELTA_RANGE = (0.0, 0.5)  # Delta > 0.5 would keep every wavelength: |x - round(x)| <= 0.5 always


@dataclass(frozen=True)
class Channel:
    """One way light reaches the camera: the table read when the camera is above
    (superstrate side) or below, whether the light crosses the grating, its component.
    """

    above: str
    below: str
    transmitted: bool
    component: int


CHANNELS = (Channel("R", "R_below", False, REFLECTION), Channel("T_below", "T", True, TRANSMISSION))


def incident_k(k_out, order: float, wavelength_nm, period_um: float):
    """Tangential k (over k0) of the incident wave that ``order`` sends to tangential
    ``k_out``: [Lange 2021, Eq. 2] solved for k_inc, with the conventions' sign.
    """
    return k_out - ORDER_SIGN * order * wavelength_nm / (1000.0 * period_um)


def implied_order(k_inc, k_out, wavelength_nm, period_um: float):
    """The (real) order that takes tangential ``k_inc`` to ``k_out`` at ``wavelength_nm``
    ([Lange 2021, Eq. 4]: the order each of the ray's wavelengths implies).
    """
    return (k_out - k_inc) * (1000.0 * period_um) / (ORDER_SIGN * wavelength_nm)


def _check_setting(name: str, value: float) -> float:
    """The changeable settings' ranges (the constructor and parameters_changed)."""
    if name == "uniform_share" and not 0.0 <= value <= 1.0:
        raise ValueError(f"bwdf: 'uniform_share' must be within [0, 1], got {value:g}")
    if name == "delta" and not DELTA_RANGE[0] < value <= DELTA_RANGE[1]:
        raise ValueError(f"bwdf: 'delta' must be within (0, 0.5] (an order's distance to an integer), got {value:g}")
    if name == "grating_angle" and not math.isfinite(value):
        raise ValueError(f"bwdf: 'grating_angle' must be a finite angle in degrees, got {value:g}")
    return value


def _check_center(center) -> tuple[float, float, float]:
    """The radial mapping's groove centre: three finite coordinates (world space)."""
    values = tuple(float(c) for c in center)
    if len(values) != 3 or not all(math.isfinite(c) for c in values):
        raise ValueError(f"bwdf: 'center' must be a point of three finite coordinates, got {list(values)}")
    return values


def _read_center(props: mi.Properties, mapping: str) -> tuple[float, float, float]:
    """``center`` from the properties: required by the radial mapping, the origin (unused)
    otherwise."""
    if "center" not in props:
        if mapping == "radial":
            raise ValueError("bwdf: the radial (CD) mapping needs 'center', the grooves' centre in world space "
                             "(e.g. [0.28, 0.023, 0.25])")
        return (0.0, 0.0, 0.0)
    value = props.get("center")
    try:
        return _check_center(value)
    except (TypeError, ValueError):
        raise ValueError(f"bwdf: 'center' must be a point of three finite coordinates, got {value!r}") from None


class GratingBWDF(DeltaLobesBSDF):
    """Diffraction orders of a periodic surface, read from an RCWA efficiency table.

    Delta lobes only (``eval`` and ``pdf`` are zero; integrators reach them through
    ``sample``): reflection, and for see-through tables transmission. The physics, the two
    modes and their weights are in the module docstring (renderer/bwdf.py).

    .. list-table:: Parameters
       :header-rows: 1

       * - Name
         - Type
         - Meaning
         - Default
       * - ``filename``
         - string
         - An efficiency table written by ``workbench rcwa table`` (rcwa.table). A table
           whose substrate transmits is see-through and must be built with
           ``--both-sides``.
         - required
       * - ``mode``
         - string
         - ``"improved"`` (hero-wavelength MIS, orders by efficiency) or ``"paper"``
           ([Lange 2021, Eqs. 2-5]: uniform orders, the Delta test).
         - ``"improved"``
       * - ``mapping``
         - string
         - Where the grating vector (the table's +x) lies in the surface: ``"constant"``,
           at ``grating_angle`` from the shading frame's s axis (a grating whose grooves
           keep one direction); ``"radial"``, outward from ``center`` at every hit point
           (circular grooves about the centre, a CD): the hit point minus the centre,
           projected onto the surface (the shading frame's tangent plane). Exact at any
           tessellation, unlike a mesh's per-triangle dp/du (a 256-segment disk is up to
           1.4 degrees off radial).
         - ``"constant"``
       * - ``center``
         - point (3 floats, world space)
         - The centre of the circular grooves. Required with the radial mapping; unused
           with the constant one. *Exposed* with the radial mapping (move it with the
           shape).
         - required (radial)
       * - ``grating_angle``
         - float, degrees
         - The grating vector's angle from the shading frame's s axis (the groove
           direction is 90 degrees from it). *Exposed* with the constant mapping.
         - 0
       * - ``uniform_share``
         - float in [0, 1]
         - Improved mode: the share of the diffracted-order choice made uniformly over the
           orders that carry light, the rest in proportion to efficiency (a defensive
           mixture). 0.5 gave the lowest noise on cornell_cd's CD, then lying flat (relative pixel noise
           at 128 spp: 0.75 at 0, 0.51 at 0.5, 0.54 at 0.8, 0.58 at 1;
           benchmarks/bench_render.py). *Exposed* in improved mode.
         - 0.5
       * - ``delta``
         - float in (0, 0.5]
         - Paper mode: the paper's Delta_x (and Delta_y), how close to an integer the
           order a non-hero wavelength implies must be for it to be kept (Eqs. 4-5).
           *Exposed* in paper mode.
         - 0.05
       * - ``superstrate_index``
         - float >= 1
         - The superstrate's index for the geometry of the orders, where it differs from
           the table's n(lambda): a CD's polycarbonate top rendered without dispersion (at
           its mean index) is the grating's superstrate, so the orders' directions inside
           it must use the same index, or their directions in air scale by
           n_top / n(lambda) (0.98 at 410 nm, 1.008 at 685 nm for polycarbonate). The table
           is still read at its own incident angle, asin(k_t / n(lambda)) for the tangential
           wave vector k_t. 0: the table's n(lambda).
         - 0

    *Exposed* parameters appear in ``mi.traverse`` under these names and may be changed
    between renders (``parameters_changed`` checks their ranges). ``BSDFContext`` is
    honoured: disabled components (reflection 0, transmission 1) are never sampled, and
    the n^2 radiance factor of transmission applies in radiance transport only.

    docs/mitsuba_plugin.md documents it for Mitsuba users (dict and XML scenes). Example::

        import mitsuba as mi
        from renderer.plugins import register_plugins
        from renderer.variant import set_variant

        set_variant()  # the one place that picks Mitsuba's variant
        register_plugins()
        cd = mi.load_dict({"type": "bwdf", "filename": "cd.zarr", "mapping": "radial", "center": [0.0, 0.0, 0.0]})
        params = mi.traverse(cd)
        params["uniform_share"] = 0.3
        params.update()
        print(cd)  # every setting
    """

    # Set from _configure's dictionary (before the base class registers the instance).
    filename: str
    mode: str
    mapping: str
    see_through: bool
    uniform_share: mi.Float
    delta: mi.Float
    grating_angle: mi.Float  # degrees
    center: mi.Point3f  # world space; the radial mapping's groove centre
    lookups: dict[str, EfficiencyLookup]
    period: tuple[float, ...]  # micrometres, (x, y); a 1D grating's y period is a dummy 1
    dimension: int
    media: tuple[str, str]
    wavelength_range: tuple[float, float, int]
    orders: list[tuple[int, int]]
    _specular_index: int | None
    _n1_axis: tuple[float, float, int]
    _n1: mi.Float
    _n3: mi.Float
    superstrate_index: float  # 0: the table's n(lambda)
    _n1_geometry: mi.Float | None  # the superstrate index of the orders' geometry, where it is not the table's

    def __init__(self, props: mi.Properties) -> None:
        # Read and validate everything before the base class registers this instance with
        # Dr.Jit: symbolic calls trace every registered BSDF, so a half-built one left
        # behind by a failed constructor would break later renders.
        config = self._configure(props)
        mi.BSDF.__init__(self, props)
        self.__dict__.update(config)
        if self.see_through:
            both = mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
            self.m_components = [mi.BSDFFlags.DeltaReflection | both,
                                 mi.BSDFFlags.DeltaTransmission | both | mi.BSDFFlags.NonSymmetric]
        else:
            self.m_components = [mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide]
        self.m_flags = self.m_components[0]
        for flags in self.m_components[1:]:
            self.m_flags = self.m_flags | flags
        for name in self._exposed():
            dr.make_opaque(getattr(self, name))

    @staticmethod
    def _configure(props: mi.Properties) -> dict:
        check_variant(mi.variant())  # registered by hand in an RGB variant, it would fail only inside a render
        path = str(props.get("filename", ""))
        if not path:
            raise ValueError("bwdf: the 'filename' property (an efficiency table) is missing")
        mode = props.get("mode", "improved")
        mapping = props.get("mapping", "constant")
        if mode not in MODES:
            raise ValueError(f"bwdf: 'mode' must be one of {MODES}, got {mode!r}")
        if mapping not in MAPPINGS:
            raise ValueError(f"bwdf: 'mapping' must be one of {MAPPINGS}, got {mapping!r}")
        settings = {name: _check_setting(name, float(props.get(name, default)))  # type: ignore[arg-type]
                    for name, default in (("uniform_share", 0.5), ("delta", 0.05), ("grating_angle", 0.0))}
        center = _read_center(props, mapping)
        superstrate_index = float(props.get("superstrate_index", 0.0))  # type: ignore[arg-type]
        if superstrate_index != 0.0 and not (math.isfinite(superstrate_index) and superstrate_index >= 1.0):
            raise ValueError(f"bwdf: 'superstrate_index' must be 0 (the table's) or a real index >= 1, "
                             f"got {superstrate_index:g}")
        table = open_table(path)  # clear errors for missing, unfinished or damaged tables
        arrays = set(table.meta["arrays"])
        see_through = "T" in arrays
        if see_through and not {"R_below", "T_below"} <= arrays:
            raise ValueError(f"bwdf: {path}: the substrate transmits, so the element is see-through and needs light "
                             "from both sides: build the table with --both-sides")
        structure = Structure.from_toml_string(table.meta["structure_text"], source=str(path))
        if mapping == "radial" and structure.dimension != 1:
            raise ValueError(f"bwdf: {path}: the radial (CD) mapping needs a 1D grating table, this one is 2D "
                             f"(period {list(structure.period)}); use mapping = \"constant\"")
        wl = table.wavelengths_nm
        grid = np.linspace(wl.min(), wl.max(), max(2, int(round((wl.max() - wl.min()) / 5.0)) + 1))
        orders = list(zip(table.meta["orders_m"], table.meta["orders_n"], strict=True))
        return {
            "filename": str(path), "mode": mode, "mapping": mapping, "see_through": see_through,
            **{name: mi.Float(value) for name, value in settings.items()},
            "center": mi.Point3f(*center),
            "lookups": {name: EfficiencyLookup.from_table(table, name) for name in ("R", "T", "R_below", "T_below")
                        if name in arrays},
            "period": tuple(structure.period) + ((1.0,) if structure.dimension == 1 else ()),
            "dimension": structure.dimension,
            "media": (structure.superstrate.name, structure.substrate.name),
            "wavelength_range": (float(wl.min()), float(wl.max()), int(wl.size)),
            "orders": orders,
            "_specular_index": next((k for k, mn in enumerate(orders) if tuple(mn) == (0, 0)), None),
            "_n1_axis": (float(grid[0]), float(grid[1] - grid[0]), grid.size),
            "_n1": mi.Float(np.real(structure.superstrate.refractive_index(grid)).astype(np.float32)),
            "_n3": mi.Float(np.real(structure.substrate.refractive_index(grid)).astype(np.float32)),
            "superstrate_index": superstrate_index,
            "_n1_geometry": mi.Float(np.full(grid.size, superstrate_index, np.float32)) if superstrate_index else None,
        }

    # ---------------------------------------------------------------- parameters

    def _exposed(self) -> list[str]:
        """The settings that change this instance's output (so mi.traverse shows them)."""
        return (["grating_angle"] if self.mapping == "constant" else ["center"]) + \
            (["uniform_share"] if self.mode == "improved" else ["delta"])

    def traverse(self, callback) -> None:
        for name in self._exposed():
            callback.put(name, getattr(self, name), mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys=None) -> None:
        for name in self._exposed():
            value = getattr(self, name)
            if dr.width(value) != 1:
                raise ValueError(f"bwdf: '{name}' must be one {'point' if name == 'center' else 'number'}, "
                                 f"got {dr.width(value)} values")
            if name == "center":
                _check_center([float(c[0]) for c in value])
            else:
                _check_setting(name, float(value[0]))
            dr.make_opaque(value)

    def to_string(self) -> str:
        media = f"superstrate {self.media[0]}, substrate {self.media[1]}"
        lo, hi, count = self.wavelength_range
        lines = [
            f'filename = "{self.filename}"',
            f'mode = "{self.mode}"',
            f'mapping = "{self.mapping}"',
            f"grating_angle = {self.grating_angle[0]:g} deg" + (" (unused: radial mapping)" if self.mapping == "radial" else ""),
            f"center = [{', '.join(f'{float(c[0]):g}' for c in self.center)}]"
            + (" (unused: constant mapping)" if self.mapping == "constant" else ""),
            f"uniform_share = {self.uniform_share[0]:g}" + ("" if self.mode == "improved" else " (unused: paper mode)"),
            f"delta = {self.delta[0]:g}" + ("" if self.mode == "paper" else " (unused: improved mode)"),
            f"components = {'[reflection, transmission] (see-through)' if self.see_through else '[reflection]'}",
            f"period_um = {list(self.period[:self.dimension])}",
            f"orders = {[tuple(int(v) for v in mn) for mn in self.orders]}",
            f"wavelengths_nm = {lo:g}-{hi:g} ({count} values)",
            f"media = {media}",
            "superstrate_index = " + (f"{self.superstrate_index:g} (the orders' geometry; the table read at its own "
                                      "angle)" if self.superstrate_index else "0 (the table's n(lambda))"),
        ]
        return "GratingBWDF[\n" + ",\n".join("  " + line for line in lines) + "\n]"

    # ---------------------------------------------------------------- helpers

    def _index(self, values: mi.Float, wavelength: mi.Float) -> mi.Float:
        start, step, count = self._n1_axis
        t = dr.clip((wavelength - start) / step, 0.0, count - 1)
        i0 = mi.UInt32(dr.minimum(dr.floor(t), count - 2))
        f = t - mi.Float(i0)
        return (1.0 - f) * dr.gather(mi.Float, values, i0) + f * dr.gather(mi.Float, values, i0 + 1)

    def _geometry_n1(self) -> mi.Float:
        """The superstrate index of the orders' directions (superstrate_index where given)."""
        return self._n1_geometry if self._n1_geometry is not None else self._n1

    def _table_theta(self, k_t, lam, light_below) -> mi.Float:
        """The table's incident theta (degrees) for tangential wave vector ``k_t`` (over k0) on the light's side:
        asin(k_t / n) with the table's own index n(lambda) of that side."""
        n_table = dr.select(light_below, self._index(self._n3, lam), self._index(self._n1, lam))
        return dr.asin(dr.clip(k_t / n_table, 0.0, 1.0)) * (180.0 / math.pi)

    def _grating_axis(self, si: mi.SurfaceInteraction3f) -> tuple[mi.Float, mi.Float]:
        if self.mapping == "constant":
            angle = self.grating_angle * (math.pi / 180.0)
            return mi.Float(dr.cos(angle)), mi.Float(dr.sin(angle))
        # Outward from the groove centre, in the tangent plane: exact at every hit point
        # (a mesh's per-triangle dp/du is not; see the class docstring).
        g = si.to_local(mi.Vector3f(si.p - self.center))
        norm = dr.sqrt(g.x * g.x + g.y * g.y)
        ok = norm > 1e-12  # the exact centre of a disk has no radial direction
        return mi.Float(dr.select(ok, g.x / norm, 1.0)), mi.Float(dr.select(ok, g.y / norm, 0.0))

    def _enabled_channels(self, ctx: mi.BSDFContext) -> list[Channel]:
        """The channels the context lets this call sample (reflection 0, transmission 1)."""
        wanted = [ctx.is_enabled(mi.BSDFFlags.DeltaReflection, REFLECTION),
                  self.see_through and ctx.is_enabled(mi.BSDFFlags.DeltaTransmission, TRANSMISSION)]
        return [c for c, on in zip(CHANNELS, wanted, strict=True) if on]

    def _incident(self, u_o, v_o, m: float, n: float, lam, n_cam, n_light, z_sign: float):
        """omega_i (grating frame) for order (m, n); propagating mask; table (theta, phi) in degrees.

        n_cam, n_light: the indices of the camera's and the light's sides.
        """
        ux = -incident_k(n_cam * u_o, m, lam, self.period[0]) / n_light
        uy = -incident_k(n_cam * v_o, n, lam, self.period[1]) / n_light
        s2 = ux * ux + uy * uy
        propagating = s2 < 1.0
        z = z_sign * dr.safe_sqrt(1.0 - s2)
        theta = dr.acos(dr.clip(dr.abs(z), 0.0, 1.0)) * (180.0 / math.pi)
        phi = dr.atan2(-uy, -ux) * (180.0 / math.pi)
        return ux, uy, z, propagating, theta, phi

    # ---------------------------------------------------------------- BSDF interface

    def _candidates(self, u_o, v_o, lam, below, valid, channels, radiance, specular=None):
        """Every (channel, order) the camera direction can come from: directions, masks,
        table angles, and efficiency times the radiance factor (n_c / n_l)^2 (radiance
        transport only). ``specular``: the specular order's efficiency at ``lam`` when
        already known.
        """
        n1, n3 = self._index(self._geometry_n1(), lam), self._index(self._n3, lam)
        n_cam = dr.select(below, n3, n1)
        out = []
        for channel in channels:
            transmitted = channel.transmitted
            n_light = dr.select(below, n1, n3) if transmitted else n_cam
            factor = (n_cam / n_light) ** 2 if transmitted and radiance else mi.Float(1.0)
            look_above, look_below = self.lookups[channel.above], self.lookups.get(channel.below)
            for k, (m, n) in enumerate(self.orders):
                ux, uy, z, prop, theta, phi = self._incident(u_o, v_o, float(m), float(n), lam, n_cam, n_light,
                                                             -1.0 if transmitted else 1.0)
                if self._n1_geometry is not None:  # the table's own incident angle for this tangential k
                    light_below = below if not transmitted else ~below
                    theta = self._table_theta(n_light * dr.sqrt(ux * ux + uy * uy), lam, light_below)
                if specular is not None and not transmitted and k == self._specular_index:
                    de = specular
                else:
                    de = look_above.eval(mi.UInt32(k), lam, theta, phi, valid & prop & ~below)
                    if look_below is not None:
                        de = dr.select(below, look_below.eval(mi.UInt32(k), lam, theta, phi, valid & prop & below), de)
                value = dr.select(prop, de * factor, 0.0)
                out.append({"ux": ux, "uy": uy, "z": z, "prop": prop, "theta": theta, "phi": phi, "value": value,
                            "transmitted": transmitted, "k": k, "n_cam": n_cam, "n_light": n_light})
        return out

    def sample(self, ctx, si, sample1, sample2, active=True):
        bs = dr.zeros(mi.BSDFSample3f)
        channels = self._enabled_channels(ctx)
        if not channels:
            return bs, mi.Spectrum(0.0)
        radiance = ctx.mode == mi.TransportMode.Radiance
        reflection = channels[0].component == REFLECTION
        wi = si.wi
        below = mi.Frame3f.cos_theta(wi) < 0  # camera on the substrate side
        active = mi.Bool(active) & (dr.abs(mi.Frame3f.cos_theta(wi)) > 0)
        if not self.see_through:
            active &= ~below
        ca, sa = self._grating_axis(si)
        u_o = wi.x * ca + wi.y * sa
        v_o = -wi.x * sa + wi.y * ca
        cos_o = dr.abs(mi.Frame3f.cos_theta(wi))
        wl = si.wavelengths
        hero, rest = choose_hero(sample1)
        lam = select([wl[i] for i in range(WAVELENGTHS_PER_RAY)], hero)

        lanes = None
        if self.mode == "improved" and reflection and self._specular_index is not None:
            lanes = self._specular_efficiencies(u_o, v_o, cos_o, wl, below, active)
        cands = self._candidates(u_o, v_o, lam, below, active, channels, radiance,
                                 select(lanes, hero) if lanes else None)
        if self.mode == "improved":
            k0 = self._specular_index if reflection else None
            chosen, pdf, weight_of = self._choose_improved(cands, lanes, k0, hero, rest)
        else:
            count = len(self.orders)
            channel = mi.UInt32(dr.minimum(dr.floor(rest * len(channels)), len(channels) - 1))
            rest2 = rest * len(channels) - mi.Float(channel)
            chosen = channel * count + mi.UInt32(dr.minimum(dr.floor(rest2 * count), count - 1))
            pdf = mi.Float(1.0 / (count * len(channels)))
        pick = lambda key: select([c[key] for c in cands], chosen)  # noqa: E731
        ux, uy, z, theta, phi = pick("ux"), pick("uy"), pick("z"), pick("theta"), pick("phi")
        transmitted = select([mi.Bool(c["transmitted"]) for c in cands], chosen)
        valid = active & select([c["prop"] for c in cands], chosen) & (pdf > 0)

        if self.mode == "improved":
            weight = weight_of(valid)
        else:
            weight = self._paper_weights(u_o, v_o, ux, uy, z, theta, phi, wl, cos_o, below, transmitted, valid,
                                         channels, radiance)

        z_world = dr.select(below, -z, z)
        bs.wo = mi.Vector3f(ux * ca - uy * sa, ux * sa + uy * ca, z_world)
        bs.pdf = dr.select(valid, pdf, 0.0)
        n_cam, n_light = pick("n_cam"), pick("n_light")
        bs.eta = dr.select(transmitted, n_light / n_cam, 1.0)
        # Mitsuba's stubs type these fields as UInt, which is UInt32 at run time in every variant
        bs.sampled_type = dr.select(transmitted, mi.UInt32(+mi.BSDFFlags.DeltaTransmission),  # type: ignore[assignment]
                                    mi.UInt32(+mi.BSDFFlags.DeltaReflection))
        bs.sampled_component = dr.select(transmitted, mi.UInt32(TRANSMISSION), mi.UInt32(REFLECTION))  # type: ignore[assignment]
        return bs, dr.select(valid, weight, 0.0)

    def _choose_improved(self, cands, lanes, k0, hero, rest):
        """Improved mode's choice: the specular order, shared by all wavelengths, or one
        diffracted (channel, order) of the hero wavelength.

        The specular reflection (order (0, 0) on the camera's side, candidate ``k0``;
        None when reflection is disabled or not kept) leaves in the same direction at every
        wavelength, so it is chosen with a probability q0 that does not depend on the
        hero: the mean of its efficiency over the ray's wavelengths. Every wavelength then
        keeps its own weight DE_i(0) / q0 (hero-wavelength MIS, [Wilkie 2014, Eq. 7],
        where all four strategies give this direction with the same probability).
        Otherwise (1 - q0) a diffracted lobe is chosen with probability (1 - a) DE /
        sum(DE) + a / (number of lobes with DE > 0) at the hero wavelength, a =
        ``uniform_share``: a defensive mixture [Hesterberg 1995]
        that keeps weak orders sampled when they carry a bright source, as the CD's
        rainbow of the ceiling light does; its direction depends on the wavelength, so the
        others are terminated and the hero is reweighted by their number (the delta-lobe
        limit of the same MIS; pbrt-v4's TerminateSecondary, [Pharr 2023]).
        ``lanes``: the specular order's efficiency at each wavelength (None without a
        specular candidate). Returns (chosen candidate, its probability, a function
        valid -> weight).
        """
        alpha = self.uniform_share
        q0 = dr.clip(sum(lanes[1:], lanes[0]) / WAVELENGTHS_PER_RAY, 0.0, 1.0) if lanes else mi.Float(0.0)
        specular = rest < q0
        rest_d = dr.clip((rest - q0) / dr.maximum(1.0 - q0, 1e-12), 0.0, 0.99999994)
        others = [i for i in range(len(cands)) if i != k0]
        total = sum((cands[i]["value"] for i in others), mi.Float(0.0))
        live = sum((mi.Float(dr.select(cands[i]["value"] > 0, 1.0, 0.0)) for i in others), mi.Float(0.0))
        # Each diffracted lobe's probability: its efficiency's share, mixed with a uniform
        # share over the lobes that carry light (defensive importance sampling).
        probs = {i: dr.select(cands[i]["value"] > 0, (1 - alpha) * cands[i]["value"] / dr.maximum(total, 1e-30)
                              + alpha / dr.maximum(live, 1.0), 0.0) for i in others}
        last = others[-1] if others else k0  # a table of the specular order alone has no others
        chosen = mi.UInt32(last)
        running = mi.Float(0.0)
        for i in others[:-1]:
            running = running + probs[i]
            chosen = dr.select((rest_d < running) & (chosen == last), i, chosen)
        p_chosen = select([probs.get(i, mi.Float(0.0)) for i in range(len(cands))], chosen)
        de_chosen = select([c["value"] for c in cands], chosen)
        diffracted_pdf = dr.select(total > 0, (1.0 - q0) * p_chosen, 0.0)
        if k0 is not None:
            chosen = dr.select(specular, mi.UInt32(k0), chosen)
        pdf = dr.select(specular, q0, diffracted_pdf)

        def weight_of(valid):
            hero_weight = WAVELENGTHS_PER_RAY * de_chosen / dr.maximum(diffracted_pdf, 1e-30)
            out = []
            for i in range(WAVELENGTHS_PER_RAY):
                shared = lanes[i] / dr.maximum(q0, 1e-12) if lanes else mi.Float(0.0)
                out.append(dr.select(valid, dr.select(specular, shared, dr.select(hero == i, hero_weight, 0.0)), 0.0))
            return mi.Spectrum(out)

        return chosen, pdf, weight_of

    def _specular_efficiencies(self, u_o, v_o, cos_o, wl, below, active):
        """Efficiency of the specular order (0, 0) on the camera's side at each of the ray's
        wavelengths, read at the mirror direction (the same for all of them).
        """
        theta = dr.acos(dr.clip(cos_o, 0.0, 1.0)) * (180.0 / math.pi)
        phi = dr.atan2(v_o, u_o) * (180.0 / math.pi)
        k = mi.UInt32(self._specular_index)
        above, under = self.lookups["R"], self.lookups.get("R_below")
        lanes = []
        for i in range(WAVELENGTHS_PER_RAY):
            if self._n1_geometry is not None:  # the table's angle for the mirror direction's tangential k
                n_cam = dr.select(below, self._index(self._n3, wl[i]), self._index(self._n1_geometry, wl[i]))
                theta = self._table_theta(n_cam * dr.safe_sqrt(1.0 - cos_o * cos_o), wl[i], below)
            de = above.eval(k, wl[i], theta, phi, active & ~below)
            if under is not None:
                de = dr.select(below, under.eval(k, wl[i], theta, phi, active & below), de)
            lanes.append(de)
        return lanes

    def _paper_weights(self, u_o, v_o, ux, uy, z, theta, phi, wl, cos_o, below, transmitted, valid, channels, radiance):
        """Eqs. 4-5: each wavelength at its own implied order, kept if within Delta; the
        order was chosen uniformly (x N_tot) and, when both components are enabled, the
        side by a fair coin (x 2); weight DE * N_tot / cos(theta_o) * |cos(theta_i)| as in
        pbrt-v3, times (n_c / n_l)^2 for transmission in radiance transport.
        """
        count = len(self.orders)
        cos_ratio = dr.abs(z) / cos_o
        weights = []
        for i in range(WAVELENGTHS_PER_RAY):
            lam_i = wl[i]
            n1, n3 = self._index(self._geometry_n1(), lam_i), self._index(self._n3, lam_i)
            n_cam = dr.select(below, n3, n1)
            n_light = dr.select(transmitted, dr.select(below, n1, n3), n_cam)
            nx = implied_order(-n_light * ux, n_cam * u_o, lam_i, self.period[0])
            ny = implied_order(-n_light * uy, n_cam * v_o, lam_i, self.period[1])
            mx = dr.sign(nx) * dr.floor(dr.abs(nx) + 0.5)
            my = dr.sign(ny) * dr.floor(dr.abs(ny) + 0.5)
            passes = valid & (dr.abs(nx - mx) < self.delta) & (dr.abs(ny - my) < self.delta)
            de = mi.Float(0.0)
            for k, (m, n) in enumerate(self.orders):
                hit = passes & (mx == m) & (my == n)
                for channel in channels:
                    sel = hit & (transmitted == channel.transmitted)
                    value = self.lookups[channel.above].eval(mi.UInt32(k), lam_i, theta, phi, sel & ~below)
                    if channel.below in self.lookups:
                        value = dr.select(below, self.lookups[channel.below].eval(mi.UInt32(k), lam_i, theta, phi,
                                                                                  sel & below), value)
                    de = dr.select(sel, value, de)
            factor = dr.select(transmitted, (n_cam / n_light) ** 2, 1.0) if radiance else 1.0
            weights.append(de * factor * count * len(channels) * cos_ratio)
        return mi.Spectrum(weights)


def register() -> None:
    """Register ``type = "bwdf"`` with Mitsuba (after renderer.variant.set_variant; renderer.plugins
    registers every plugin at once)."""
    check_variant(mi.variant())
    mi.register_bsdf("bwdf", lambda props: GratingBWDF(props))

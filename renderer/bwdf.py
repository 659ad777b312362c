"""The BWDF: a grating's diffraction orders as a Mitsuba 3 BSDF plugin (``type = "bwdf"``).

Parameters (Mitsuba properties)
-------------------------------
filename : string
    An efficiency table written by ``workbench rcwa table`` (rcwa.table).
mode : string, default "improved"
    ``"paper"`` reproduces Lange et al. 2021, Eqs. 2-5: one of the N_tot kept orders
    chosen uniformly, one of the ray's wavelengths at random (the hero), the incident
    direction from Eqs. 2-3, the Delta test (Eq. 4-5) for the other wavelengths, each read
    at its own implied order, and the weight DE * N_tot / cos(theta_o) times pbrt's
    |cos(theta_i)| (pbrt-v3's f * |cos| / pdf). ``"improved"`` is hero-wavelength MIS
    (Wilkie et al. 2014) for delta lobes: the specular order, whose direction is the same
    at every wavelength, is chosen with the mean of its efficiency over the ray's
    wavelengths and keeps all of them (weight DE_i(0) / q0 each); otherwise a diffracted
    order is chosen at the hero wavelength (by efficiency, mixed with a uniform share: see
    ``uniform_share``) and the other wavelengths are terminated, the hero reweighted by
    their number (pbrt-v4's TerminateSecondary, the limit of that MIS when the directions
    differ).
mapping : string, default "constant"
    How the grating vector (the table's +x) lies in the surface: ``"constant"``, at
    ``grating_angle`` degrees from the shading frame's s axis; ``"radial"``, along the
    shape's dp/du (Mitsuba's disk: radial, so circular grooves about the centre, as on a
    CD).
grating_angle : float, default 0
delta : float, default 0.05
    The paper's Delta_x (and Delta_y): tolerance of the implied order in paper mode.
uniform_share : float in [0, 1], default 0.5
    Improved mode: the share of the diffracted-order choice made uniformly over the
    orders that carry light, the rest in proportion to efficiency. 0.5 gave the lowest
    noise on cornell_cd's CD (relative pixel noise at 128 spp: 0.75 at 0, 0.51 at 0.5,
    0.54 at 0.8, 0.58 at 1; benchmarks/bench_render.py).

Weights, and where paper mode differs. Mitsuba's ``sample`` returns f |cos| / pdf. A
grating order maps direction cosines (times the superstrate index) by a translation,
which preserves projected solid angle, so a radiance L_i arriving along the order's
incident direction leaves as DE * L_i: improved mode's weight per chosen order is
DE / p(order). The paper's
pbrt-v3 weight carries an extra cos(theta_i)/cos(theta_o); paper mode keeps it, as
written, so the two can be compared (the accuracy-vs-time study reports the difference).

See-through elements (tables built with ``--both-sides`` and a transmitting substrate):
four channels, for a camera above (superstrate side) or below: reflection from the
camera's side and transmission from the other (R, T_below above; R_below, T below). The
grating equation keeps the tangential wave vector: n_l omega_i,t = -n_c omega_o,t -
(m lambda / Lambda_x, n lambda / Lambda_y) with the indices of the light's and camera's
sides, and a transmitted radiance scales by (n_c / n_l)^2 (the n^2 law of radiance).
Improved mode samples orders of all channels by efficiency; paper mode tosses a fair
coin between reflection and transmission (weight x2), as the paper's Sec. 2.2 does.

Directions (Mitsuba's si.wi is the paper's omega_o, toward the camera; bs.wo is its
omega_i, toward the light). In the grating frame, order (m, n) relates them by the
grating equation with the order sign of workbench.core.conventions:
    omega_i,t = -omega_o,t - (m lambda / (n1 Lambda_x), n lambda / (n1 Lambda_y)),
and the table is read at the incident wave's (theta, phi): theta of omega_i and the
azimuth of -omega_i,t.
"""

from __future__ import annotations

import math

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

MODES = ("paper", "improved")
MAPPINGS = ("constant", "radial")


class GratingBWDF(DeltaLobesBSDF):
    def __init__(self, props: mi.Properties) -> None:
        # Read and validate everything before the base class registers this instance with
        # Dr.Jit: symbolic calls trace every registered BSDF, so a half-built one left
        # behind by a failed constructor would break later renders.
        config = self._configure(props)
        mi.BSDF.__init__(self, props)
        self.__dict__.update(config)
        self.m_flags = mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide
        if self.see_through:
            self.m_flags = self.m_flags | mi.BSDFFlags.DeltaTransmission | mi.BSDFFlags.BackSide
        self.m_components = [self.m_flags]

    @staticmethod
    def _configure(props: mi.Properties) -> dict:
        path = props.get("filename", "")
        if not path:
            raise ValueError("bwdf: the 'filename' property (an efficiency table) is missing")
        mode = props.get("mode", "improved")
        mapping = props.get("mapping", "constant")
        if mode not in MODES:
            raise ValueError(f"bwdf: 'mode' must be one of {MODES}, got {mode!r}")
        uniform_share = float(props.get("uniform_share", 0.5))
        if not 0.0 <= uniform_share <= 1.0:
            raise ValueError(f"bwdf: 'uniform_share' must be within [0, 1], got {uniform_share}")
        if mapping not in MAPPINGS:
            raise ValueError(f"bwdf: 'mapping' must be one of {MAPPINGS}, got {mapping!r}")
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
        return {
            "mode": mode, "mapping": mapping, "see_through": see_through,
            "angle": math.radians(props.get("grating_angle", 0.0)), "delta": float(props.get("delta", 0.05)),
            "uniform_share": uniform_share,
            "lookups": {name: EfficiencyLookup.from_table(table, name) for name in ("R", "T", "R_below", "T_below")
                        if name in arrays},
            "period": tuple(structure.period) + ((1.0,) if structure.dimension == 1 else ()),
            "orders": list(zip(table.meta["orders_m"], table.meta["orders_n"])),
            "_specular_index": next((k for k, mn in enumerate(zip(table.meta["orders_m"], table.meta["orders_n"]))
                                     if tuple(mn) == (0, 0)), None),
            "_n1_axis": (float(grid[0]), float(grid[1] - grid[0]), grid.size),
            "_n1": mi.Float(np.real(structure.superstrate.refractive_index(grid)).astype(np.float32)),
            "_n3": mi.Float(np.real(structure.substrate.refractive_index(grid)).astype(np.float32)),
        }

    # ---------------------------------------------------------------- helpers

    def _index(self, values: mi.Float, wavelength: mi.Float) -> mi.Float:
        start, step, count = self._n1_axis
        t = dr.clip((wavelength - start) / step, 0.0, count - 1)
        i0 = mi.UInt32(dr.minimum(dr.floor(t), count - 2))
        f = t - mi.Float(i0)
        return (1.0 - f) * dr.gather(mi.Float, values, i0) + f * dr.gather(mi.Float, values, i0 + 1)

    def _grating_axis(self, si: mi.SurfaceInteraction3f) -> tuple[mi.Float, mi.Float]:
        if self.mapping == "constant":
            return mi.Float(math.cos(self.angle)), mi.Float(math.sin(self.angle))
        g = si.to_local(si.dp_du)
        norm = dr.sqrt(g.x * g.x + g.y * g.y)
        ok = norm > 1e-12  # the exact centre of a disk has no radial direction
        return dr.select(ok, g.x / norm, 1.0), dr.select(ok, g.y / norm, 0.0)

    def _incident(self, u_o, v_o, m: float, n: float, lam, n1, n_light=None, z_sign: float = 1.0):
        """omega_i (grating frame) for order (m, n); propagating mask; table (theta, phi) in degrees.

        n1: the camera side's index; n_light: the light side's (default: the same side).
        """
        n_light = n1 if n_light is None else n_light
        ux = (-n1 * u_o - m * lam / (1000.0 * self.period[0])) / n_light
        uy = (-n1 * v_o - n * lam / (1000.0 * self.period[1])) / n_light
        s2 = ux * ux + uy * uy
        propagating = s2 < 1.0
        z = z_sign * dr.safe_sqrt(1.0 - s2)
        theta = dr.acos(dr.clip(dr.abs(z), 0.0, 1.0)) * (180.0 / math.pi)
        phi = dr.atan2(-uy, -ux) * (180.0 / math.pi)
        return ux, uy, z, propagating, theta, phi

    # ---------------------------------------------------------------- BSDF interface

    def _candidates(self, u_o, v_o, lam, below, valid, specular=None):
        """Every (channel, order) the camera direction can come from: directions, masks,
        table angles, and efficiency times the radiance factor (n_c / n_l)^2.
        ``specular``: the specular order's efficiency at ``lam`` when already known."""
        n1, n3 = self._index(self._n1, lam), self._index(self._n3, lam)
        n_cam = dr.select(below, n3, n1)
        out = []
        channels = [("R", "R_below", False)] + ([("T_below", "T", True)] if self.see_through else [])
        for above_name, below_name, transmitted in channels:
            n_light = dr.select(below, n1, n3) if transmitted else n_cam
            factor = (n_cam / n_light) ** 2 if transmitted else mi.Float(1.0)
            for k, (m, n) in enumerate(self.orders):
                ux, uy, z, prop, theta, phi = self._incident(u_o, v_o, float(m), float(n), lam, n_cam, n_light,
                                                             -1.0 if transmitted else 1.0)
                look_above, look_below = self.lookups[above_name], self.lookups.get(below_name)
                if specular is not None and not transmitted and k == self._specular_index:
                    de = specular
                else:
                    de = look_above.eval(mi.UInt32(k), lam, theta, phi, valid & prop & ~below)
                    if look_below is not None:
                        de = dr.select(below, look_below.eval(mi.UInt32(k), lam, theta, phi, valid & prop & below), de)
                value = dr.select(prop, de * factor, 0.0)
                out.append({"ux": ux, "uy": uy, "z": z, "prop": prop, "theta": theta, "phi": phi, "value": value,
                            "transmitted": transmitted, "k": k, "n_cam": n_cam, "n_light": n_light, "factor": factor})
        return out

    def sample(self, ctx, si, sample1, sample2, active=True):
        bs = dr.zeros(mi.BSDFSample3f)
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
        if self.mode == "improved" and self._specular_index is not None:
            lanes = self._specular_efficiencies(u_o, v_o, cos_o, wl, below, active)
        cands = self._candidates(u_o, v_o, lam, below, active, select(lanes, hero) if lanes else None)
        if self.mode == "improved":
            chosen, pdf, weight_of = self._choose_improved(cands, lanes, hero, rest)
        else:
            count = len(self.orders)
            channels = 2 if self.see_through else 1
            channel = mi.UInt32(dr.minimum(dr.floor(rest * channels), channels - 1))
            rest2 = rest * channels - mi.Float(channel)
            chosen = channel * count + mi.UInt32(dr.minimum(dr.floor(rest2 * count), count - 1))
            pdf = mi.Float(1.0 / (count * channels))
        pick = lambda key: select([c[key] for c in cands], chosen)  # noqa: E731
        ux, uy, z, theta, phi = pick("ux"), pick("uy"), pick("z"), pick("theta"), pick("phi")
        transmitted = select([mi.Bool(c["transmitted"]) for c in cands], chosen)
        valid = active & select([c["prop"] for c in cands], chosen) & (pdf > 0)

        if self.mode == "improved":
            weight = weight_of(valid)
        else:
            weight = self._paper_weights(u_o, v_o, ux, uy, z, theta, phi, wl, cos_o, below, transmitted, chosen, valid)

        z_world = dr.select(below, -z, z)
        bs.wo = mi.Vector3f(ux * ca - uy * sa, ux * sa + uy * ca, z_world)
        bs.pdf = dr.select(valid, pdf, 0.0)
        n_cam, n_light = pick("n_cam"), pick("n_light")
        bs.eta = dr.select(transmitted, n_light / n_cam, 1.0)
        bs.sampled_type = dr.select(transmitted, mi.UInt32(+mi.BSDFFlags.DeltaTransmission),
                                    mi.UInt32(+mi.BSDFFlags.DeltaReflection))
        bs.sampled_component = mi.UInt32(0)
        return bs, dr.select(valid, weight, 0.0)

    def _choose_improved(self, cands, lanes, hero, rest):
        """Improved mode's choice: the specular order, shared by all wavelengths, or one
        diffracted (channel, order) of the hero wavelength.

        The specular reflection (order (0, 0) on the camera's side) leaves in the same
        direction at every wavelength, so it is chosen with a probability q0 that does not
        depend on the hero: the mean of its efficiency over the ray's wavelengths. Every
        wavelength then keeps its own weight DE_i(0) / q0 (hero-wavelength MIS, Wilkie et
        al. 2014, Eq. 7, where all four strategies give this direction with the same
        probability). Otherwise (1 - q0) a diffracted lobe is chosen with probability
        (1 - a) DE / sum(DE) + a / (number of lobes with DE > 0) at the hero wavelength, a =
        ``uniform_share``: a defensive mixture (Hesterberg 1995, Technometrics 37, 185) that
        keeps weak orders sampled when they carry a bright source, as the CD's rainbow of
        the ceiling light does; its direction depends on the wavelength, so the
        others are terminated and the hero is reweighted by their number (the delta-lobe
        limit of the same MIS; pbrt-v4's TerminateSecondary).
        ``lanes``: the specular order's efficiency at each wavelength (None when the table
        has no specular order). Returns (chosen candidate, its probability, a function
        valid -> weight).
        """
        alpha = self.uniform_share
        k0 = self._specular_index
        q0 = dr.clip(sum(lanes[1:], lanes[0]) / WAVELENGTHS_PER_RAY, 0.0, 1.0) if lanes else mi.Float(0.0)
        specular = rest < q0
        rest_d = dr.clip((rest - q0) / dr.maximum(1.0 - q0, 1e-12), 0.0, 0.99999994)
        others = [i for i in range(len(cands)) if i != k0]
        total = sum((cands[i]["value"] for i in others), mi.Float(0.0))
        live = sum((dr.select(cands[i]["value"] > 0, 1.0, 0.0) for i in others), mi.Float(0.0))
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
        wavelengths, read at the mirror direction (the same for all of them)."""
        theta = dr.acos(dr.clip(cos_o, 0.0, 1.0)) * (180.0 / math.pi)
        phi = dr.atan2(v_o, u_o) * (180.0 / math.pi)
        k = mi.UInt32(self._specular_index)
        above, under = self.lookups["R"], self.lookups.get("R_below")
        lanes = []
        for i in range(WAVELENGTHS_PER_RAY):
            de = above.eval(k, wl[i], theta, phi, active & ~below)
            if under is not None:
                de = dr.select(below, under.eval(k, wl[i], theta, phi, active & below), de)
            lanes.append(de)
        return lanes

    def _paper_weights(self, u_o, v_o, ux, uy, z, theta, phi, wl, cos_o, below, transmitted, chosen, valid):
        """Eqs. 4-5: each wavelength at its own implied order, kept if within Delta; the
        order was chosen uniformly (x N_tot) and, for see-through elements, the side by a
        fair coin (x 2); weight DE * N_tot / cos(theta_o) * |cos(theta_i)| as in pbrt-v3."""
        count = len(self.orders)
        channels = 2 if self.see_through else 1
        cos_ratio = dr.abs(z) / cos_o
        weights = []
        for i in range(WAVELENGTHS_PER_RAY):
            lam_i = wl[i]
            n1, n3 = self._index(self._n1, lam_i), self._index(self._n3, lam_i)
            n_cam = dr.select(below, n3, n1)
            n_light = dr.select(transmitted, dr.select(below, n1, n3), n_cam)
            nx = (-n_light * ux - n_cam * u_o) * 1000.0 * self.period[0] / lam_i
            ny = (-n_light * uy - n_cam * v_o) * 1000.0 * self.period[1] / lam_i
            mx = dr.sign(nx) * dr.floor(dr.abs(nx) + 0.5)
            my = dr.sign(ny) * dr.floor(dr.abs(ny) + 0.5)
            passes = valid & (dr.abs(nx - mx) < self.delta) & (dr.abs(ny - my) < self.delta)
            de = mi.Float(0.0)
            names = (("R", "R_below"), ("T_below", "T"))
            for k, (m, n) in enumerate(self.orders):
                hit = passes & (mx == m) & (my == n)
                for t_flag, (above_name, below_name) in enumerate(names[:channels]):
                    sel = hit & (transmitted == bool(t_flag))
                    value = self.lookups[above_name].eval(mi.UInt32(k), lam_i, theta, phi, sel & ~below)
                    if below_name in self.lookups:
                        value = dr.select(below, self.lookups[below_name].eval(mi.UInt32(k), lam_i, theta, phi, sel & below), value)
                    de = dr.select(sel, value, de)
            factor = dr.select(transmitted, (n_cam / n_light) ** 2, 1.0)
            weights.append(de * factor * count * channels * cos_ratio)
        return mi.Spectrum(weights)



    def to_string(self):
        return f"GratingBWDF[mode={self.mode}, mapping={self.mapping}, orders={len(self.orders)}]"


def register() -> None:
    """Register ``type = "bwdf"`` with Mitsuba (after renderer.variant.set_variant)."""
    mi.register_bsdf("bwdf", lambda props: GratingBWDF(props))

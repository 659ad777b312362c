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
    |cos(theta_i)| (pbrt-v3's f * |cos| / pdf). ``"improved"`` chooses the order in
    proportion to its efficiency at the hero wavelength and terminates the other
    wavelengths, reweighting the hero by their number (pbrt-v4's TerminateSecondary; the
    limit of hero-wavelength MIS, Wilkie et al. 2014, for delta lobes).
mapping : string, default "constant"
    How the grating vector (the table's +x) lies in the surface: ``"constant"``, at
    ``grating_angle`` degrees from the shading frame's s axis; ``"radial"``, along the
    shape's dp/du (Mitsuba's disk: radial, so circular grooves about the centre, as on a
    CD).
grating_angle : float, default 0
delta : float, default 0.05
    The paper's Delta_x (and Delta_y): tolerance of the implied order in paper mode.

Weights, and where paper mode differs. Mitsuba's ``sample`` returns f |cos| / pdf. A
grating order maps direction cosines (times the superstrate index) by a translation,
which preserves projected solid angle, so a radiance L_i arriving along the order's
incident direction leaves as DE * L_i: improved mode's weight per chosen order is
DE / p(order), i.e. the sum of the efficiencies of all propagating orders. The paper's
pbrt-v3 weight carries an extra cos(theta_i)/cos(theta_o); paper mode keeps it, as
written, so the two can be compared (the accuracy-vs-time study reports the difference).

Directions (Mitsuba's si.wi is the paper's omega_o, toward the camera; bs.wo is its
omega_i, toward the light). In the grating frame, order (m, n) relates them by the
grating equation with the order sign of workbench.conventions:
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
from renderer.efficiency import EfficiencyLookup

MODES = ("paper", "improved")
MAPPINGS = ("constant", "radial")
WAVELENGTHS_PER_RAY = 4


class GratingBWDF(mi.BSDF):
    def __init__(self, props: mi.Properties) -> None:
        mi.BSDF.__init__(self, props)
        path = props.get("filename", "")
        if not path:
            raise ValueError("bwdf: the 'filename' property (an efficiency table) is missing")
        self.mode = props.get("mode", "improved")
        self.mapping = props.get("mapping", "constant")
        if self.mode not in MODES:
            raise ValueError(f"bwdf: 'mode' must be one of {MODES}, got {self.mode!r}")
        if self.mapping not in MAPPINGS:
            raise ValueError(f"bwdf: 'mapping' must be one of {MAPPINGS}, got {self.mapping!r}")
        self.angle = math.radians(props.get("grating_angle", 0.0))
        self.delta = float(props.get("delta", 0.05))
        table = open_table(path)  # clear errors for missing, unfinished or damaged tables
        self.lookup = EfficiencyLookup.from_table(table, "R")
        structure = Structure.from_toml_string(table.meta["structure_text"], source=str(path))
        if self.mapping == "radial" and structure.dimension != 1:
            raise ValueError(f"bwdf: {path}: the radial (CD) mapping needs a 1D grating table, this one is 2D "
                             f"(period {list(structure.period)}); use mapping = \"constant\"")
        self.period = tuple(structure.period) + ((1.0,) if structure.dimension == 1 else ())
        self.orders = list(zip(table.meta["orders_m"], table.meta["orders_n"]))
        wl = table.wavelengths_nm
        grid = np.linspace(wl.min(), wl.max(), max(2, int(round((wl.max() - wl.min()) / 5.0)) + 1))
        self._n1_axis = (float(grid[0]), float(grid[1] - grid[0]), grid.size)
        self._n1 = mi.Float(np.real(structure.superstrate.refractive_index(grid)).astype(np.float32))
        self.m_flags = mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide
        self.m_components = [self.m_flags]

    # ---------------------------------------------------------------- helpers

    def _superstrate_index(self, wavelength: mi.Float) -> mi.Float:
        start, step, count = self._n1_axis
        t = dr.clip((wavelength - start) / step, 0.0, count - 1)
        i0 = mi.UInt32(dr.minimum(dr.floor(t), count - 2))
        f = t - mi.Float(i0)
        return (1.0 - f) * dr.gather(mi.Float, self._n1, i0) + f * dr.gather(mi.Float, self._n1, i0 + 1)

    def _grating_axis(self, si: mi.SurfaceInteraction3f) -> tuple[mi.Float, mi.Float]:
        if self.mapping == "constant":
            return mi.Float(math.cos(self.angle)), mi.Float(math.sin(self.angle))
        g = si.to_local(si.dp_du)
        norm = dr.sqrt(g.x * g.x + g.y * g.y)
        ok = norm > 1e-12  # the exact centre of a disk has no radial direction
        return dr.select(ok, g.x / norm, 1.0), dr.select(ok, g.y / norm, 0.0)

    def _incident(self, u_o, v_o, m: float, n: float, lam, n1):
        """omega_i (grating frame) for order (m, n); propagating mask; table (theta, phi) in degrees."""
        ux = -u_o - m * lam / (1000.0 * n1 * self.period[0])
        uy = -v_o - n * lam / (1000.0 * n1 * self.period[1])
        s2 = ux * ux + uy * uy
        propagating = s2 < 1.0
        z = dr.safe_sqrt(1.0 - s2)
        theta = dr.acos(dr.clip(z, 0.0, 1.0)) * (180.0 / math.pi)
        phi = dr.atan2(-uy, -ux) * (180.0 / math.pi)
        return ux, uy, z, propagating, theta, phi

    # ---------------------------------------------------------------- BSDF interface

    def sample(self, ctx, si, sample1, sample2, active=True):
        bs = dr.zeros(mi.BSDFSample3f)
        wi = si.wi
        active = mi.Bool(active) & (mi.Frame3f.cos_theta(wi) > 0)
        ca, sa = self._grating_axis(si)
        u_o = wi.x * ca + wi.y * sa
        v_o = -wi.x * sa + wi.y * ca
        wl = si.wavelengths
        hero = dr.minimum(dr.floor(sample1 * WAVELENGTHS_PER_RAY), WAVELENGTHS_PER_RAY - 1)
        rest = sample1 * WAVELENGTHS_PER_RAY - hero
        lam = dr.select(hero == 0, wl[0], dr.select(hero == 1, wl[1], dr.select(hero == 2, wl[2], wl[3])))
        n1 = self._superstrate_index(lam)

        per_order = [self._incident(u_o, v_o, float(m), float(n), lam, n1) for m, n in self.orders]
        count = len(self.orders)
        if self.mode == "improved":
            de = [dr.select(d[3], self.lookup.eval(mi.UInt32(k), lam, d[4], d[5], active & d[3]), 0.0)
                  for k, d in enumerate(per_order)]
            total = sum(de[1:], de[0])
            target = rest * total
            chosen = mi.UInt32(count - 1)
            running = mi.Float(0.0)
            for k in range(count - 1):
                running = running + de[k]
                chosen = dr.select((target < running) & (chosen == count - 1), k, chosen)
            chosen_de = self._pick(de, chosen)
            pdf = dr.select(total > 0, chosen_de / total, 0.0)
        else:
            chosen = mi.UInt32(dr.minimum(dr.floor(rest * count), count - 1))
            pdf = mi.Float(1.0 / count)
        ux = self._pick([d[0] for d in per_order], chosen)
        uy = self._pick([d[1] for d in per_order], chosen)
        z = self._pick([d[2] for d in per_order], chosen)
        propagating = self._pick_bool([d[3] for d in per_order], chosen)
        theta = self._pick([d[4] for d in per_order], chosen)
        phi = self._pick([d[5] for d in per_order], chosen)
        valid = active & propagating & (pdf > 0)

        if self.mode == "improved":
            weight_hero = WAVELENGTHS_PER_RAY * total
            weight = mi.Spectrum([dr.select(valid & (hero == i), weight_hero, 0.0) for i in range(WAVELENGTHS_PER_RAY)])
        else:
            weight = self._paper_weights(u_o, v_o, ux, uy, z, theta, phi, wl, wi, count, valid)

        bs.wo = mi.Vector3f(ux * ca - uy * sa, ux * sa + uy * ca, z)
        bs.pdf = dr.select(valid, pdf, 0.0)
        bs.eta = 1.0
        bs.sampled_type = mi.UInt32(+mi.BSDFFlags.DeltaReflection)
        bs.sampled_component = mi.UInt32(0)
        return bs, dr.select(valid, weight, 0.0)

    def _paper_weights(self, u_o, v_o, ux, uy, z, theta, phi, wl, wi, count, valid):
        """Eqs. 4-5: each wavelength at its own implied order, kept if within Delta."""
        weights = []
        cos_ratio = z / mi.Frame3f.cos_theta(wi)
        for i in range(WAVELENGTHS_PER_RAY):
            lam_i = wl[i]
            n1 = self._superstrate_index(lam_i)
            nx = (-ux - u_o) * n1 * 1000.0 * self.period[0] / lam_i
            ny = (-uy - v_o) * n1 * 1000.0 * self.period[1] / lam_i
            mx = dr.sign(nx) * dr.floor(dr.abs(nx) + 0.5)
            my = dr.sign(ny) * dr.floor(dr.abs(ny) + 0.5)
            passes = (dr.abs(nx - mx) < self.delta) & (dr.abs(ny - my) < self.delta)
            de = mi.Float(0.0)
            for k, (m, n) in enumerate(self.orders):
                hit = passes & (mx == m) & (my == n)
                de = dr.select(hit, self.lookup.eval(mi.UInt32(k), lam_i, theta, phi, valid & hit), de)
            weights.append(de * count * cos_ratio)
        return mi.Spectrum(weights)

    @staticmethod
    def _pick(values, index):
        out = values[0]
        for k in range(1, len(values)):
            out = dr.select(index == k, values[k], out)
        return out

    @staticmethod
    def _pick_bool(values, index):
        out = values[0]
        for k in range(1, len(values)):
            out = dr.select(index == k, values[k], out)
        return out

    def eval(self, ctx, si, wo, active=True):
        return mi.Spectrum(0.0)  # delta lobes only: zero for any given pair of directions

    def pdf(self, ctx, si, wo, active=True):
        return mi.Float(0.0)

    def eval_pdf(self, ctx, si, wo, active=True):
        return mi.Spectrum(0.0), mi.Float(0.0)

    def traverse(self, callback):
        pass

    def to_string(self):
        return f"GratingBWDF[mode={self.mode}, mapping={self.mapping}, orders={len(self.orders)}]"


def register() -> None:
    """Register ``type = "bwdf"`` with Mitsuba (after renderer.variant.set_variant)."""
    mi.register_bsdf("bwdf", lambda props: GratingBWDF(props))

"""A dispersive smooth dielectric: a Mitsuba 3 BSDF plugin (``type = "dispersive_dielectric"``).

Mitsuba's ``dielectric`` takes one scalar index. Glass and the CD's polycarbonate top
have n(lambda) (rcwa.materials: N-BK7, fused silica, polycarbonate, with their
citations), and the four wavelengths a Mitsuba spectral ray carries refract into four
different directions. This plugin is ``dielectric`` with the index looked up per
wavelength.

Physics. At a smooth interface with relative index eta = n_int / n_ext the unpolarised
Fresnel reflectance is R = (R_s + R_p) / 2 with
    r_s = (cos_i - eta cos_t) / (cos_i + eta cos_t),  r_p = (eta cos_i - cos_t) / (eta cos_i + cos_t),
and Snell's law sin_i = eta sin_t (for light arriving from inside, eta -> 1 / eta; R = 1
beyond the critical angle); T = 1 - R ([Born 1999, Sec. 1.5.2];
[Pharr 2023, Sec. 9.3]).
Mitsuba's ``mi.fresnel`` evaluates exactly these, per wavelength here. A transmitted
radiance is scaled by (n_ext / n_int)^2 in radiance transport (the n^2 law), as Mitsuba's
``dielectric`` does.

Sampling (``sample``), the approach of pbrt-v4 ([Pharr 2023]:
its DielectricMaterial calls SampledWavelengths::TerminateSecondary when eta is not
constant) and of renderer.bwdf's improved mode. ``sample1`` picks a hero wavelength h
uniformly among the ray's four and then reflection with probability R(lambda_h), else
transmission:
  * transmission: the direction is Snell's for lambda_h alone, so the other wavelengths
    are terminated (weight 0) and lambda_h is reweighted by their number: weight
    4 * (n_ext / n_int(lambda_h))^2 (the probability of this outcome is T_h / 4 and the
    lobe's value is T_h, per wavelength);
  * reflection: the mirror direction is the same for every wavelength, so none is
    terminated; the probability of reflecting, summed over the four hero choices, is
    mean_j R_j, and wavelength j gets R_j / mean_j R_j (one-sample MIS over the heroes).
Per wavelength the expected weight is R_j + T_j = 1 (before the n^2 factor): unbiased, and
for a non-dispersive index (every R_j equal) it reduces to ``dielectric`` except that
transmission still keeps one wavelength.

One consequence, shared with renderer.bwdf: a BSDF in Mitsuba's path integrator cannot
tell whether the path's other wavelengths were already terminated (pbrt-v4 keeps that
state in SampledWavelengths), so every transmission picks a new hero; a path through a
second dispersive interface survives with probability 1/4 at 4x weight. Still unbiased,
but noisier behind several dispersive interfaces (see docs/architecture.md).

Parameters (Mitsuba properties)
-------------------------------
wavelength_min, wavelength_max : float
    The range (nm) of the index table; ``index`` holds evenly spaced values over it.
index : string
    Comma-separated real refractive indices of the inside material, linearly
    interpolated in wavelength and held constant beyond the range.
ext_ior : float, default 1
    The (non-dispersive) index outside: air, as in the paper.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from renderer.delta_lobes import (
    WAVELENGTHS_PER_RAY,
    DeltaLobesBSDF,
    choose_hero,
    select,
)
from renderer.scene import SPECTRAL_RANGE_NM

INDEX_STEP_NM = 1.0


class DispersiveDielectric(DeltaLobesBSDF):
    # Set in __init__ from _configure's dict (validated before Dr.Jit registers the instance).
    lo: float  # nm, the first wavelength of the index table
    step: float  # nm between table entries
    count: int  # table entries
    ext: float  # the index outside
    mean_index: float  # of the inside material, for to_string
    _eta_np: np.ndarray  # the relative index table n_int / n_ext
    _eta_jit: mi.Float | None  # the same table for gathers in JIT variants; None in scalar ones

    def __init__(self, props: mi.Properties) -> None:
        # Validate before the base class registers the instance with Dr.Jit (as bwdf.py).
        config = self._configure(props)
        mi.BSDF.__init__(self, props)
        self.__dict__.update(config)
        reflection = mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
        transmission = (mi.BSDFFlags.DeltaTransmission | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
                        | mi.BSDFFlags.NonSymmetric)
        self.m_components = [reflection, transmission]
        self.m_flags = reflection | transmission

    @staticmethod
    def _configure(props: mi.Properties) -> dict:
        for key in ("wavelength_min", "wavelength_max", "index"):
            if key not in props:
                raise ValueError(f"dispersive_dielectric: the '{key}' property is missing")
        lo, hi = _number(props, "wavelength_min"), _number(props, "wavelength_max")
        try:
            values = np.array([float(x) for x in str(props.get("index")).split(",")])
        except ValueError:
            raise ValueError("dispersive_dielectric: 'index' must be comma-separated numbers") from None
        ext = _number(props, "ext_ior", 1.0)
        if values.size < 2 or not hi > lo:
            raise ValueError("dispersive_dielectric: 'index' needs at least two values over wavelength_min < wavelength_max")
        if not (np.all(np.isfinite(values)) and np.all(values > 0) and ext > 0):
            raise ValueError("dispersive_dielectric: refractive indices must be finite and > 0")
        step = (hi - lo) / (values.size - 1)
        table = values / ext
        table_jit = mi.Float(table.astype(np.float32)) if dr.is_jit_v(mi.Float) else None
        return {"lo": lo, "step": step, "count": int(values.size), "ext": ext, "_eta_np": table,
                "_eta_jit": table_jit, "mean_index": float(values.mean())}

    # ---------------------------------------------------------------- helpers

    def eta(self, wavelength):
        """Relative index n_int / n_ext at ``wavelength`` (nm): linear in the table, clamped."""
        if self._eta_jit is None:  # scalar variants: plain Python floats
            return float(np.interp(float(wavelength), self.lo + self.step * np.arange(self.count), self._eta_np))
        t = dr.clip((wavelength - self.lo) / self.step, 0.0, self.count - 1)
        i0 = mi.UInt32(dr.minimum(dr.floor(t), self.count - 2))
        f = t - mi.Float(i0)
        return (1.0 - f) * dr.gather(mi.Float, self._eta_jit, i0) + f * dr.gather(mi.Float, self._eta_jit, i0 + 1)


    # ---------------------------------------------------------------- BSDF interface

    def sample(self, ctx, si, sample1, sample2, active=True):
        bs = dr.zeros(mi.BSDFSample3f)
        has_r = ctx.is_enabled(mi.BSDFFlags.DeltaReflection, 0)
        has_t = ctx.is_enabled(mi.BSDFFlags.DeltaTransmission, 1)
        cos_i = mi.Frame3f.cos_theta(si.wi)
        active = mi.Bool(active) & (cos_i != 0.0)
        if not (has_r or has_t):
            return bs, mi.Spectrum(0.0)

        n = WAVELENGTHS_PER_RAY
        hero, rest = choose_hero(sample1)
        fresnel = [mi.fresnel(cos_i, self.eta(si.wavelengths[j])) for j in range(n)]
        r = [f[0] for f in fresnel]
        r_h = select(r, hero)
        cos_t_h = select([f[1] for f in fresnel], hero)
        eta_it_h = select([f[2] for f in fresnel], hero)
        eta_ti_h = select([f[3] for f in fresnel], hero)
        radiance = ctx.mode == mi.TransportMode.Radiance
        factor = eta_ti_h * eta_ti_h if radiance else 1.0

        r_mean = sum(r[1:], r[0]) * (1.0 / n)
        weight_r: list  # per wavelength: Dr.Jit Floats, or plain 0.0 where nothing reflects
        if has_r and has_t:
            reflect = rest <= r_h
            weight_r = [dr.select(r_mean > 0, r[j] / r_mean, 0.0) for j in range(n)]
            weight_t = n * factor  # the hero's T_h / (T_h / n)
            pdf = dr.select(reflect, r_mean, (1.0 - r_h) / n)
        elif has_r:
            reflect = mi.Bool(True)
            weight_r, weight_t, pdf = r, 0.0, mi.Float(1.0)
        else:
            reflect = mi.Bool(False)
            weight_r, weight_t, pdf = [0.0] * n, n * (1.0 - r_h) * factor, mi.Float(1.0 / n)

        weight = mi.Spectrum([dr.select(reflect, weight_r[j], dr.select(hero == j, weight_t, 0.0)) for j in range(n)])
        bs.wo = dr.select(reflect, mi.reflect(si.wi), mi.refract(si.wi, cos_t_h, eta_ti_h))
        bs.eta = dr.select(reflect, 1.0, eta_it_h)
        bs.pdf = pdf
        # Mitsuba's stubs type mi.UInt32 apart from the drjit.auto.ad.UInt of BSDFSample3f's fields;
        # at run time both are the variant's one UInt32 class.
        bs.sampled_type = dr.select(reflect, mi.UInt32(+mi.BSDFFlags.DeltaReflection),  # type: ignore[assignment]
                                    mi.UInt32(+mi.BSDFFlags.DeltaTransmission))
        bs.sampled_component = dr.select(reflect, mi.UInt32(0), mi.UInt32(1))  # type: ignore[assignment]
        valid = active & (pdf > 0)
        bs.pdf = dr.select(valid, bs.pdf, 0.0)
        return bs, dr.select(valid, weight, 0.0)


    def to_string(self):
        return f"DispersiveDielectric[mean index {self.mean_index:.5f}, ext_ior {self.ext}]"


def _number(props: mi.Properties, key: str, default: float | None = None) -> float:
    """A numeric property (``mi.Properties.get`` is typed ``object``; numbers and numeric strings pass)."""
    value = props.get(key, default)
    if not isinstance(value, (int, float, str)):
        raise ValueError(f"dispersive_dielectric: '{key}' must be a number, got {value!r}")
    return float(value)


def index_curve(material, step_nm: float = INDEX_STEP_NM) -> tuple[np.ndarray, np.ndarray]:
    """A material's real index on a regular grid over the renderer's spectral range
    (renderer.scene.SPECTRAL_RANGE_NM); held constant beyond the material's data range."""
    lo, hi = SPECTRAL_RANGE_NM
    grid = np.linspace(lo, hi, round((hi - lo) / step_nm) + 1)
    covered = grid if material.wavelength_range_nm is None else np.clip(grid, *material.wavelength_range_nm)
    return grid, np.real(np.asarray(material.refractive_index(covered)))


def mean_index(material) -> float:
    """The non-dispersive fallback: the mean of n over the spectral range (uniform in lambda)."""
    return float(index_curve(material)[1].mean())


def bsdf_dict(material, *, dispersion: bool = True, ext_ior: float = 1.0) -> dict:
    """The Mitsuba BSDF for a glass (or polycarbonate) material: dispersive, or Mitsuba's
    ``dielectric`` at the mean index."""
    grid, n = index_curve(material)
    if not dispersion:
        return {"type": "dielectric", "int_ior": float(n.mean()), "ext_ior": ext_ior}
    return {"type": "dispersive_dielectric", "wavelength_min": float(grid[0]), "wavelength_max": float(grid[-1]),
            "index": ", ".join(f"{x:.7f}" for x in n), "ext_ior": ext_ior}


def register() -> None:
    """Register ``type = "dispersive_dielectric"`` with Mitsuba (after renderer.variant.set_variant)."""
    mi.register_bsdf("dispersive_dielectric", lambda props: DispersiveDielectric(props))

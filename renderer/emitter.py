"""A power-cosine area light: a Mitsuba 3 emitter plugin (``type = "cospower_area"``).

Mitsuba's ``area`` emitter is Lambertian only (its ``radiance`` texture may vary over
the surface, never with direction), and no built-in emitter has a cos^n lobe, so this
Python plugin, attached to a shape like ``area``, emits

    L(x, omega, lambda) = radiance(lambda) * cos^n(theta),   theta from the shape's normal,

on the normal's side only: the usual model of an LED array whose lenses narrow the beam
(n = 0 is Lambertian, and then equals ``area`` exactly). Its radiant intensity per unit
area is L0 cos^(n+1)(theta), so the total power is

    P = L0 * A * integral over the hemisphere of cos^(n+1)(theta) d omega = L0 * A * 2 pi / (n + 2),

which renderer.mitsuba_scene uses to turn the scene's ``power_w`` into L0.

Parameters (Mitsuba properties)
-------------------------------
radiance : spectrum or texture
    L0(lambda), the radiance along the normal (W m^-2 sr^-1 nm^-1).
cos_power : float, default 0
    n >= 0.

Sampling. ``sample_direction`` samples the shape by solid angle at the reference point
(the shape's own ``sample_direction``: uniform area sampling converted to solid angle,
as ``area`` does for uniform textures) and weights by radiance * cos^n / pdf;
``pdf_direction`` is that same pdf and ``eval``/``eval_direction`` the radiance, so the
path integrator's MIS between light and BSDF sampling stays consistent. ``sample_ray``
(light tracing) samples a position uniformly and the direction in proportion to
cos^(n+1) (cos theta = u^(1/(n+2))), whose weight is the constant A * 2 pi / (n + 2)
times the spectral weight. Everything is written with Dr.Jit operations, so the plugin
is traced into the kernel in the LLVM variants and runs (slowly, per sample, in Python)
in the scalar ones.
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi


class CosPowerAreaEmitter(mi.Emitter):
    # Set in __init__ from _configure's dict (validated before Dr.Jit registers the instance).
    radiance: mi.Texture  # L0(lambda)
    n: float  # the cosine power

    def __init__(self, props: mi.Properties) -> None:
        # Validate before the base class registers the instance with Dr.Jit (as bwdf.py).
        config = self._configure(props)
        mi.Emitter.__init__(self, props)
        self.__dict__.update(config)
        self.m_flags = mi.EmitterFlags.Surface
        if self.radiance.is_spatially_varying():
            self.m_flags = self.m_flags | mi.EmitterFlags.SpatiallyVarying

    @staticmethod
    def _configure(props: mi.Properties) -> dict:
        if "radiance" not in props:
            raise ValueError("cospower_area: the 'radiance' property (a spectrum) is missing")
        cos_power = props.get("cos_power", 0.0)
        if not isinstance(cos_power, (int, float, str)):  # mi.Properties.get is typed object
            raise ValueError(f"cospower_area: 'cos_power' must be a finite number >= 0, got {cos_power!r}")
        n = float(cos_power)
        if not (math.isfinite(n) and n >= 0.0):
            raise ValueError(f"cospower_area: 'cos_power' must be a finite number >= 0, got {n}")
        return {"radiance": props.get("radiance"), "n": n}

    # ---------------------------------------------------------------- helpers

    def _profile(self, cos_theta):
        """cos^n(theta) on the emitting side, 0 behind."""
        front = cos_theta > 0.0
        if self.n == 0.0:
            return dr.select(front, 1.0, 0.0)
        return dr.select(front, dr.power(dr.maximum(cos_theta, 1e-30), self.n), 0.0)

    def _emitter_ptr(self):
        return mi.EmitterPtr(self) if dr.is_jit_v(mi.Float) else self

    # ---------------------------------------------------------------- Emitter interface

    def eval(self, si, active=True):
        cos_theta = mi.Frame3f.cos_theta(si.wi)
        return self.radiance.eval(si, active) * self._profile(cos_theta)

    def sample_direction(self, it, sample, active=True):
        ds = self.get_shape().sample_direction(it, sample, active)
        # drjit's stub wants both arguments of dot() of one type; a Vector3f and a Normal3f are valid.
        cos_e = -dr.dot(ds.d, ds.n)  # type: ignore[misc]
        active = mi.Bool(active) & (cos_e > 0.0) & (ds.pdf != 0.0)
        si = mi.SurfaceInteraction3f(ds, it.wavelengths)
        value = self.radiance.eval(si, active) * self._profile(cos_e) / ds.pdf
        ds.emitter = self._emitter_ptr()
        return ds, dr.select(active, value, 0.0)

    def pdf_direction(self, it, ds, active=True):
        active = mi.Bool(active) & (dr.dot(ds.d, ds.n) < 0.0)
        return dr.select(active, self.get_shape().pdf_direction(it, ds, active), 0.0)

    def eval_direction(self, it, ds, active=True):
        cos_e = -dr.dot(ds.d, ds.n)
        active = mi.Bool(active) & (cos_e > 0.0)
        si = mi.SurfaceInteraction3f(ds, it.wavelengths)
        return dr.select(active, self.radiance.eval(si, active) * self._profile(cos_e), 0.0)

    def sample_position(self, time, sample, active=True):
        ps = self.get_shape().sample_position(time, sample, active)
        return ps, dr.select(ps.pdf > 0.0, dr.rcp(ps.pdf), 0.0)

    def pdf_position(self, ps, active=True):
        return self.get_shape().pdf_position(ps, active)

    def sample_wavelengths(self, si, sample, active=True):
        return self.radiance.sample_spectrum(si, mi.UnpolarizedSpectrum(mi.sample_shifted(sample)), active)

    def sample_ray(self, time, sample1, sample2, sample3, active=True):
        ps, pos_weight = self.sample_position(time, sample2, active)
        cos_theta = dr.power(sample3.x, 1.0 / (self.n + 2.0))
        sin_theta = dr.safe_sqrt(1.0 - cos_theta * cos_theta)
        s, c = dr.sincos(2.0 * math.pi * sample3.y)
        local = mi.Vector3f(sin_theta * c, sin_theta * s, cos_theta)
        si = mi.SurfaceInteraction3f(ps, dr.zeros(mi.UnpolarizedSpectrum))
        wavelengths, wav_weight = self.sample_wavelengths(si, sample1, active)
        si.time = time
        si.wavelengths = wavelengths
        weight = wav_weight * pos_weight * (2.0 * math.pi / (self.n + 2.0))
        return si.spawn_ray(si.to_world(local)), dr.select(active, weight, 0.0)

    def bbox(self):
        return self.get_shape().bbox()

    def traverse(self, callback):
        # Same key as Mitsuba's area emitter (``<shape>.emitter.radiance.values``), so
        # renderer.rerender scales either kind of light in place.
        callback.put("radiance", self.radiance, mi.ParamFlags.Differentiable)

    def to_string(self):
        return f"CosPowerAreaEmitter[cos_power={self.n}, radiance={self.radiance}]"


def register() -> None:
    """Register ``type = "cospower_area"`` with Mitsuba (after renderer.variant.set_variant)."""
    mi.register_emitter("cospower_area", lambda props: CosPowerAreaEmitter(props))

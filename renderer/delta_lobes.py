"""What the workbench's delta-lobe BSDFs (renderer.bwdf, renderer.dielectric) share.

A Mitsuba spectral ray carries WAVELENGTHS_PER_RAY wavelengths. A lobe whose direction
depends on the wavelength (a diffraction order, a refraction) follows one of them, the
"hero", chosen uniformly from the first random number; what remains of that number is
rescaled to [0, 1) for the next choice (the sample-reuse trick of pbrt-v4's
SampledWavelengths::TerminateSecondary, [Pharr 2023], and of [Veach 1997, Sec. 2.5.2] on
reusing samples). Delta lobes have no density for a given pair of directions, so eval and pdf
are zero (Mitsuba's convention for delta BSDFs; its integrators reach them only through
sample()).
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

WAVELENGTHS_PER_RAY = 4


def choose_hero(sample1):
    """(hero index in 0..3 as a Float, the rest of ``sample1`` rescaled to [0, 1))."""
    hero = dr.minimum(dr.floor(sample1 * WAVELENGTHS_PER_RAY), WAVELENGTHS_PER_RAY - 1)
    return hero, sample1 * WAVELENGTHS_PER_RAY - hero


def select(values, index):
    """values[index] per lane, for a short Python list of Dr.Jit values."""
    out = values[0]
    for k in range(1, len(values)):
        out = dr.select(index == k, values[k], out)
    return out


class DeltaLobesBSDF(mi.BSDF):
    """Base of a BSDF made of delta lobes only: eval and pdf are zero; nothing to traverse
    unless a subclass exposes settings (renderer.bwdf does)."""

    def eval(self, ctx, si, wo, active=True):
        return mi.Spectrum(0.0)

    def pdf(self, ctx, si, wo, active=True):
        return mi.Float(0.0)

    def eval_pdf(self, ctx, si, wo, active=True):
        return mi.Spectrum(0.0), mi.Float(0.0)

    def traverse(self, callback):
        pass

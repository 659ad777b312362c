"""The workbench's Mitsuba plugins, registered in one call (docs/mitsuba_plugin.md).

``register_plugins()`` registers, for Mitsuba's current variant, ``bwdf`` (renderer.bwdf: a
grating's diffraction orders from an RCWA efficiency table), ``dispersive_dielectric``
(renderer.dielectric) and ``cospower_area`` (renderer.emitter). The plugins compute per
wavelength, so they need one of Mitsuba's unpolarized spectral variants; any other variant is
refused here, by name, instead of failing inside a render (an RGB variant loaded the BWDF and
then stopped with ``IndexError: mitsuba.Color0f.__getitem__()``).
"""

from __future__ import annotations

SPECTRAL_VARIANTS = ("scalar_spectral", "llvm_ad_spectral", "cuda_ad_spectral")


def check_variant(variant: str | None) -> None:
    """Refuse a Mitsuba variant the plugins cannot run in (None: no variant set yet).

    Parameters
    ----------
    variant
        Mitsuba's current variant, as ``mitsuba.variant()`` gives it.

    Raises
    ------
    RuntimeError
        When no variant is set, or it is not one of SPECTRAL_VARIANTS.
    """
    choices = ", ".join(SPECTRAL_VARIANTS)
    if variant is None:
        raise RuntimeError(f"set a Mitsuba variant before registering the workbench's plugins: one of {choices} "
                           "(renderer.variant.set_variant() picks llvm_ad_spectral where libLLVM is found)")
    if variant not in SPECTRAL_VARIANTS:
        raise RuntimeError(f"the workbench's plugins (bwdf, dispersive_dielectric, cospower_area) need a spectral, "
                           f"unpolarized Mitsuba variant: one of {choices}; the current variant is {variant!r} "
                           "(an RGB or mono variant has no wavelengths to read the efficiency tables at)")


def register_plugins() -> None:
    """Register ``bwdf``, ``dispersive_dielectric`` and ``cospower_area`` for Mitsuba's current variant.

    Raises
    ------
    RuntimeError
        When Mitsuba's variant is not one of SPECTRAL_VARIANTS (check_variant).
    """
    import mitsuba as mi  # deferred: importing this module must not load Mitsuba

    check_variant(mi.variant())
    from renderer import bwdf, dielectric, emitter  # deferred: they need the variant set

    for module in (bwdf, emitter, dielectric):
        module.register()

"""The workbench's Mitsuba plugins, registered in one call (docs/mitsuba_plugin.md).

``register_plugins()`` registers, for Mitsuba's current variant, ``bwdf`` (renderer.bwdf: a
grating's diffraction orders from an RCWA efficiency table), ``dispersive_dielectric``
(renderer.dielectric) and ``cospower_area`` (renderer.emitter). The plugins compute per
wavelength, so they need one of Mitsuba's unpolarized spectral variants; any other variant is
refused here, by name, instead of failing inside a render (an RGB variant loaded the BWDF and
then stopped with ``IndexError: mitsuba.Color0f.__getitem__()``).
"""

from __future__ import annotations


def register_plugins() -> None:
    """Register ``bwdf``, ``dispersive_dielectric`` and ``cospower_area`` for Mitsuba's current variant.

    Raises
    ------
    RuntimeError
        When Mitsuba's variant is not one of renderer.variant.SPECTRAL_VARIANTS (check_variant).
    """
    import mitsuba as mi  # deferred: importing this module must not load Mitsuba

    from renderer.variant import check_variant

    check_variant(mi.variant())
    from renderer import bwdf, dielectric, emitter  # deferred: they need the variant set

    for module in (bwdf, emitter, dielectric):
        module.register()

"""The scene's spectra: Mitsuba ``irregular`` spectra, the light's emission, the camera's sensitivities.

Spectra are Mitsuba ``irregular`` spectra over 360-830 nm (renderer.scene.SPECTRAL_RANGE_NM);
data that stop inside that range (the Cornell reflectances, 400-700 nm) are held constant
beyond their ends. The CIE illuminants and the camera sensitivities are colour-science's
(colour.SDS_ILLUMINANTS, colour.MSDS_CAMERA_SENSITIVITIES); the Cornell light's emission is
the measured box's (renderer/data/cornell_box.json).
"""

from __future__ import annotations

import numpy as np

from renderer.scene import SPECTRAL_RANGE_NM, cornell_data

GRID_NM = np.arange(SPECTRAL_RANGE_NM[0], SPECTRAL_RANGE_NM[1] + 1e-9, 5.0)

Curves = list[tuple[np.ndarray, np.ndarray]]  # (wavelengths in nm, values) per camera channel


def irregular(wavelengths, values) -> dict:
    """Mitsuba's ``irregular`` spectrum of samples, held constant out to SPECTRAL_RANGE_NM."""
    wl = np.asarray(wavelengths, dtype=float)
    vals = np.asarray(values, dtype=float)
    if wl[0] > SPECTRAL_RANGE_NM[0]:
        wl, vals = np.r_[SPECTRAL_RANGE_NM[0], wl], np.r_[vals[0], vals]
    if wl[-1] < SPECTRAL_RANGE_NM[1]:
        wl, vals = np.r_[wl, SPECTRAL_RANGE_NM[1]], np.r_[vals, vals[-1]]
    return {"type": "irregular", "wavelengths": ", ".join(f"{w:g}" for w in wl), "values": ", ".join(f"{x:.6g}" for x in vals)}


def light_spectrum(name: str) -> tuple[np.ndarray, np.ndarray]:
    """The light's relative spectrum on GRID_NM: ``flat``, ``cornell`` or a CIE illuminant's name."""
    if name == "flat":
        return GRID_NM, np.ones_like(GRID_NM)
    if name == "cornell":
        e = cornell_data()["light_emission"]
        return GRID_NM, np.interp(GRID_NM, e["wavelength_nm"], e["value"])
    import colour  # deferred: start-up time

    sd = colour.SDS_ILLUMINANTS[name]
    return GRID_NM, np.interp(GRID_NM, sd.wavelengths, sd.values, left=0.0, right=0.0)


def camera_sensitivities(name: str) -> Curves:
    """The camera's three channel sensitivities (colour-science's data set ``name``)."""
    import colour  # deferred: start-up time

    msds = colour.MSDS_CAMERA_SENSITIVITIES[name]
    return [(msds.wavelengths, msds.values[:, i]) for i in range(3)]


def light_camera_rgb(light: str, sensitivities: str) -> np.ndarray:
    """(3,) the camera RGB of the light ``light`` on a reflectance-1 white diffuser: the integral of
    sensitivity x emission on the light's grid (trapezoidal). The previews' white balance
    (renderer.preview) and the report's display matrix (reports.compare.images) both take it."""
    wl, emission = light_spectrum(light)
    return np.array([np.trapezoid(np.interp(wl, w, s, left=0, right=0) * emission, wl)
                     for w, s in camera_sensitivities(sensitivities)])


def on_common_grid(curves: Curves) -> tuple[np.ndarray, np.ndarray]:
    """The channels on the union of their wavelengths (nm), zero outside each one's data:
    wavelengths (N,) and curves (channels, N)."""
    wl = np.unique(np.concatenate([w for w, _ in curves]))
    return wl, np.stack([np.interp(wl, w, s, left=0, right=0) for w, s in curves])

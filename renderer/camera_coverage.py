"""Checks made before rendering, so that a render never runs on inputs it cannot honour."""

from __future__ import annotations

import numpy as np

from workbench.core.errors import UserInputError

# A camera "sees" a wavelength where any channel's sensitivity is at least this fraction
# of the largest sensitivity of any channel. Beyond that, a missing table contributes at
# most 1 % to a channel, below the noise of a raw photo; the renderer then gives zero
# there silently (renderer.efficiency).
SENSITIVITY_THRESHOLD = 0.01


def visible_range(
    wavelengths_nm: np.ndarray, sensitivities: np.ndarray, threshold: float = SENSITIVITY_THRESHOLD
) -> tuple[float, float]:
    """The wavelength range where any channel (rows of ``sensitivities``) is >= threshold * peak."""
    s = np.atleast_2d(np.asarray(sensitivities, dtype=float))
    seen = np.any(s >= threshold * s.max(), axis=0)
    if not seen.any():
        raise UserInputError("the camera's spectral sensitivities are all zero", field="camera.sensitivities")
    wl = np.asarray(wavelengths_nm, dtype=float)
    return float(wl[seen].min()), float(wl[seen].max())


def require_table_covers_camera(table_path: str, table_wavelengths_nm: np.ndarray, camera_wavelengths_nm: np.ndarray,
                                sensitivities: np.ndarray, threshold: float = SENSITIVITY_THRESHOLD) -> None:
    lo, hi = visible_range(camera_wavelengths_nm, sensitivities, threshold)
    t_lo, t_hi = float(np.min(table_wavelengths_nm)), float(np.max(table_wavelengths_nm))
    if lo < t_lo or hi > t_hi:
        raise UserInputError(
            f"the efficiency table covers {t_lo:g}-{t_hi:g} nm but the camera is sensitive over {lo:g}-{hi:g} nm "
            f"(where a channel reaches {threshold:.0%} of the peak sensitivity)",
            file=table_path, expected=f"a table covering at least {lo:g}-{hi:g} nm (--wavelengths)",
        )

"""Checks made before rendering, so that a render never runs on inputs it cannot honour: the tables
cover the camera's sensitivities; the camera is in the box or before its open front, looking in
(renderer.scene's placement checks call these when a scene loads)."""

from __future__ import annotations

import numpy as np

from renderer.camera import CameraModel
from workbench.core.errors import UserInputError

# A camera "sees" a wavelength where any channel's sensitivity is at least this fraction
# of the largest sensitivity of any channel. Beyond that, a missing table contributes at
# most 1 % to a channel, below the noise of a raw photo; the renderer then gives zero
# there silently (renderer.efficiency).
SENSITIVITY_THRESHOLD = 0.01
# A camera before the box whose image is under this share on the box's open front sees little of the scene:
# a warning, not a refusal (a close-up of the CD is legitimate). The built-in scenes' cameras: 100 %.
LITTLE_OF_THE_BOX = 0.25


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


def check_camera_placement(camera: CameraModel, lo: np.ndarray, hi: np.ndarray, pose_field: str) -> float:
    """The camera inside the box, or in front of its open face (z < 0) and looking into it, not in or behind
    a wall (1 mm clearance). Returns the share of its image that looks into the box (rays on a 17 x 13 grid)."""
    origin = -camera.world_to_camera[:3, :3].T @ camera.world_to_camera[:3, 3]
    explicit = pose_field == "camera.world_to_camera"
    clearance = 1e-3
    inside = np.all(origin > lo + clearance) and np.all(origin < hi - clearance)
    in_front = origin[2] < lo[2] - clearance and lo[0] - 1.0 < origin[0] < hi[0] + 1.0
    if not (inside or in_front):
        raise UserInputError("the camera is inside or behind a wall of the box",
                             field=pose_field if explicit else f"{pose_field}.origin",
                             expected=f"inside the box ({lo.round(3).tolist()} to {hi.round(3).tolist()} m) "
                                      "or in front of its open side (z < 0)",
                             got=origin.round(4).tolist())
    if inside:
        return 1.0
    grid = np.stack(np.meshgrid(np.linspace(0, camera.width - 1, 17), np.linspace(0, camera.height - 1, 13)), -1)
    _, rays = camera.pixel_rays(grid.reshape(-1, 2))
    with np.errstate(divide="ignore", invalid="ignore"):
        hits = origin[:2] + ((lo[2] - origin[2]) / rays[:, 2])[:, None] * rays[:, :2]
        share = float(np.mean((rays[:, 2] > 0) & np.all((hits >= lo[:2]) & (hits <= hi[:2]), axis=1)))
    if share == 0:
        raise UserInputError("the camera looks away from the box: no ray of its image enters the box's open front",
                             field=pose_field if explicit else f"{pose_field}.target",
                             expected=f"a view into the open front (z = {lo[2]:.4g} m, x {lo[0]:.4g} to {hi[0]:.4g}, "
                                      f"y {lo[1]:.4g} to {hi[1]:.4g} m)", got=origin.round(4).tolist())
    return share


def camera_view_warnings(camera: CameraModel, centers: list, share: float, little: float = LITTLE_OF_THE_BOX) -> tuple[str, ...]:
    """What a legitimate but suspicious camera misses: most of the box, or every CD and grating."""
    warnings = []
    if share < little:
        warnings.append(f"the camera sees little of the box: its open front fills {share:.0%} of the image")
    if centers:
        points = np.asarray(centers, float)
        depth = (points @ camera.world_to_camera[:3, :3].T + camera.world_to_camera[:3, 3])[:, 2]
        ahead = points[depth > 0]
        px = camera.project(ahead) if len(ahead) else np.zeros((0, 2))
        if not np.any(np.all((px >= -0.5) & (px <= [camera.width - 0.5, camera.height - 0.5]), axis=1)):
            warnings.append("the camera sees none of the CDs and gratings (their centres fall outside its image)")
    return tuple(warnings)

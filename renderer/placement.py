"""Where the scene's objects sit in the world: frames and 4x4 transforms (metres).

The one definition of each object's placement, shared by the Mitsuba scene
(renderer.mitsuba_scene), the planner and calibration's scene model
(calibration.pose.scene_model), so that what calibration aligns with is what the renderer draws.
Mitsuba's shapes are placed from their canonical forms: a ``rectangle`` spans [-1, 1]^2 in
the xy-plane with normal +z, a ``cube`` spans [-1, 1]^3, the CD's annulus mesh lies in the
xy-plane (renderer.meshes).
"""

from __future__ import annotations

import math

import numpy as np

from renderer.scene import CD_TOP_THICKNESS_M, MM, CDSpec, GlassSpec, GratingSpec, LightSpec


def frame_to(normal, rotation_deg: float) -> np.ndarray:
    """Rotation taking +z to ``normal``, after rotating by ``rotation_deg`` about z."""
    n = np.asarray(normal, dtype=float)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, n)
    s, c = np.linalg.norm(axis), float(np.dot(z, n))
    if s < 1e-12:
        R = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    else:
        k = axis / s
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        R = np.eye(3) + s * K + (1 - c) * K @ K
    a = math.radians(rotation_deg)
    Rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    return R @ Rz


def transform(translation, rotation: np.ndarray, scale=(1.0, 1.0, 1.0)) -> np.ndarray:
    """The 4x4 transform: scale along the local axes, rotate, then translate."""
    T = np.eye(4)
    T[:3, :3] = rotation @ np.diag(scale)
    T[:3, 3] = translation
    return T


def box_points_m(points_mm, scale=(1.0, 1.0, 1.0)) -> np.ndarray:
    """Points of the measured Cornell box (mm) in metres, scaled per axis to the scene's box
    (renderer.scene.box_scale)."""
    return np.asarray(points_mm, dtype=float) * MM * np.asarray(scale)


def cd_top_center(cd: CDSpec) -> np.ndarray:
    """The centre of a CD's flat polycarbonate top: CD_TOP_THICKNESS_M above the grating,
    along its normal."""
    return np.asarray(cd.center) + CD_TOP_THICKNESS_M * np.asarray(cd.normal)


def glass_cube_to_world(glass: GlassSpec) -> np.ndarray:
    """A glass cube's transform from Mitsuba's [-1, 1]^3 (cube_to_world of the scene's cube)."""
    return cube_to_world(glass.center, glass.size, glass.rotation_deg)


def cube_to_world(center, size: float, rotation_deg: float) -> np.ndarray:
    """A cube's transform from Mitsuba's [-1, 1]^3: edge ``size``, turned by ``rotation_deg``
    about the world's y axis (upright), centred at ``center``."""
    c, s = math.cos(math.radians(rotation_deg)), math.sin(math.radians(rotation_deg))
    R = frame_to([0, 0, 1], 0.0) @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])  # about y
    return transform(center, R, (size / 2,) * 3)


def light_to_world(light: LightSpec) -> np.ndarray:
    """The ceiling light's rectangle from Mitsuba's [-1, 1]^2: ``size`` along world x and z,
    facing down (-y), centred at ``center``."""
    down = frame_to([0.0, -1.0, 0.0], 0.0)
    return transform(light.center, down, (light.size[0] / 2, light.size[1] / 2, 1))


def grating_to_world(grating: GratingSpec) -> np.ndarray:
    """A grating plate's rectangle from Mitsuba's [-1, 1]^2: ``size`` along its grating frame's
    x and y (frame_to of its normal and rotation), centred at ``center``."""
    R = frame_to(grating.normal, grating.rotation_deg)
    return transform(grating.center, R, (grating.size[0] / 2, grating.size[1] / 2, 1.0))

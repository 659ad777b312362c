"""The calibration set of ``workbench synth``: a checkerboard held in the box in seeded poses,
seen by view0's camera with its flash on (calibration/board*.dng and board.json).

The flash (a point light at the camera's centre, ``board.flash`` in truth.json) lights every
pose, where the ceiling light alone lit only boards turned up towards it (datasets_synthetic.synth
says why the poses need it). The board views are rendered with Mitsuba's ``direct`` integrator
(BOARD_INTEGRATOR): what OpenCV reads in them, the board's corners, is drawn by the direct light
of the flash and the ceiling light on the board's squares; the box's interreflections add a smooth
fill (measured on two of seed 0's first board poses at 640 x 480: the board 2.3-3.2 % darker without
it), and the corners land where the path tracer's land (tests/datasets_synthetic/test_board_views.py).
One board view costs about 0.3 of the path tracer's at depth 8 (1.1 s against 3.7 s, mean of
three poses rendered in one process, loaded machine); ``max_depth`` 2 renders the same image
as ``direct`` in 1.4 s, depth 3 in 1.9 s. The scene's photos (photos/,
brackets/) keep the scene's path tracer: they are what renders are compared with.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np

from datasets_synthetic.board import BOARD_KEY, Checkerboard, corners_visible, sample_pose
from datasets_synthetic.sensor import auto_exposure
from renderer.rerender import FitRenderer
from renderer.spectra import irregular, light_spectrum

FLASH_KEY = "calibration_flash"
FLASH_W_PER_SR = 20.0
BOARD_FORMAT = "workbench-board"
BOARD_INTEGRATOR = "direct"  # Mitsuba's direct-light integrator for the board views (module docstring)
BOARD_SEED_OFFSET = 500  # board view i renders with the frame seed of frame 500 + i (after the scene's views)


def calibration_set(hidden, camera, board: Checkerboard, p: dict, light_scale: float, seed_of: Callable[[int], int],
                    writer: Any, rngs: tuple[np.random.Generator, np.random.Generator], bar,
                    renders: Any) -> dict[str, np.ndarray]:
    """Board views from view0's camera, its flash on: seeded poses in which nothing hides the board.

    ``seed_of``: a frame's Mitsuba seed from its index; ``writer`` and ``renders``: synth's
    frame writer and render store; ``rngs``: the board poses' and the sensor noise's
    generators. Returns each file's board_to_world."""
    import mitsuba as mi  # deferred: start-up time

    rng_board, rng_noise = rngs
    first = sample_pose(board, camera, rng_board, view=0)
    fit = FitRenderer(hidden, resolution=(camera.width, camera.height), spp=p["calibration_spp"],
                      extra_objects={BOARD_KEY: board.mitsuba_shape(mi, first), FLASH_KEY: flash(hidden, camera)},
                      integrator=BOARD_INTEGRATOR)
    fit.set(light_power_scale=light_scale)
    poses: dict[str, np.ndarray] = {}
    pose = first
    for i in range(p["calibration_views"]):
        while True:
            fit.move(BOARD_KEY, board.shape_matrix(pose))
            if corners_visible(mi, fit.scene, board, pose, camera):
                break
            pose = sample_pose(board, camera, rng_board, view=i)
        name = f"board{i:02d}"
        rgb = renders.get(name, partial(fit.render, seed=seed_of(BOARD_SEED_OFFSET + i)))
        writer.capture("calibration", name, rgb, auto_exposure(rgb, writer.sensor), camera, rng_noise)
        poses[f"{name}.dng"] = pose
        if i + 1 < p["calibration_views"]:
            pose = sample_pose(board, camera, rng_board, view=i + 1)
        bar.update()
    return poses


def board_description(board: Checkerboard) -> dict:
    """calibration/board.json: the board of the calibration views (the format
    calibration.dataset reads: ``kind`` "checkerboard", ``inner_corners`` [cols, rows] as
    OpenCV's patternSize counts them, ``square_mm``)."""
    return {"format": BOARD_FORMAT, "kind": "checkerboard", "inner_corners": list(board.inner_corners),
            "square_mm": round(board.square_size_m * 1000.0, 9)}


def flash(spec, camera) -> dict:
    """The photographer's flash: a point light at the camera's centre with the scene light's
    spectrum and radiant intensity FLASH_W_PER_SR (W/sr), so that it outshines the ceiling
    light on the board (80 W/m^2 at 0.5 m, against about 25 W/m^2 at 35 cm from the
    10 W ceiling light).
    """
    wl, s = light_spectrum(spec.light.spectrum)
    centre = np.linalg.inv(camera.world_to_camera)[:3, 3]
    return {"type": "point", "position": centre.tolist(), "intensity": irregular(wl, s * FLASH_W_PER_SR / np.trapezoid(s, wl))}

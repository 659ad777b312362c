"""``calibrate DATASET``'s vignetting stage: the lens's falloff from every photo's walls
(calibration.intrinsics.vignetting), and the exposure scales re-read on the lens's axis.

The data are the pose's render check's (calibration.pose.render_check): its last merged
render of the scene file seen by the fitted camera (within RESCALE_AFTER_PX of the final
pose, which a 16-pixel tile of a wall does not see) against the photo, over the walls, in
tiles, for every linear photo (a raw, or a non-raw file with the bracket's inverse
response). So the stage renders nothing. Where the fit is applied (a corner falloff over
3 std and 5 %), each photo's ``exposure_scale`` becomes photo / (V render) over those
tiles, the exposure on the lens's axis (the pose's, photo / render, is lowered by the
walls' mean falloff), and its ``exposure_scale_std`` the spread of that ratio over 4 x 4
blocks of the image, as the pose states its own; a render at the calibrated exposure,
times V, is then the photo.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from calibration.intrinsics.vignetting import CHANNELS, WallTiles, falloff, fit_vignetting

MIN_TILES = 50
BLOCKS = 4  # per side, as calibration.pose.render_check's scale spread


def vignetting_stage(results: dict) -> tuple[dict, dict]:
    """(calibration.json's ``vignetting``, the results (calibration.pose.stages.PoseResult by photo
    name) with exposure scales on the axis where it is applied)."""
    tick = time.perf_counter()
    tiles: dict[str, WallTiles] = {name: r.wall_tiles for name, r in results.items() if r.wall_tiles is not None}
    if sum(t.x.size for t in tiles.values()) < MIN_TILES:
        why = ("the pose's render check was off or no photo is linear" if not tiles else
               f"fewer than {MIN_TILES} wall tiles in the linear photos")
        return {"applied": False, "why": f"not fitted: {why}"}, results
    first = next(iter(tiles))
    record = fit_vignetting(tiles, results[first].camera)
    record["render_spp"] = {name: results[name].log.get("render_check", {}).get("spp") for name in tiles}
    if record["applied"]:
        results = dict(results)
        record["exposure_scale_before"] = {}
        for name, t in tiles.items():
            scale, spread = _scale_on_axis(t, record, results[name].camera)
            record["exposure_scale_before"][name] = results[name].exposure_scale
            results[name] = dataclasses.replace(results[name], exposure_scale=scale, exposure_scale_std=spread)
    record["seconds"] = time.perf_counter() - tick
    return record, results


def _scale_on_axis(tiles: WallTiles, record: dict, camera) -> tuple[float, float]:
    """The scale photo / (V render), channel sums over the tiles, and its spread over BLOCKS x BLOCKS blocks."""
    v = np.stack([falloff(np.asarray(record["coefficients"][ch], float), tiles.x) for ch in CHANNELS], axis=1)
    photo, seen = tiles.photo_sum.sum(axis=1), (tiles.render_sum * v).sum(axis=1)
    block = ((tiles.centre[:, 1] * BLOCKS // camera.height) * BLOCKS + tiles.centre[:, 0] * BLOCKS // camera.width)
    ratios = [photo[block == b].sum() / seen[block == b].sum() for b in np.unique(block) if np.sum(block == b) >= 2]
    spread = float(np.std(ratios, ddof=1)) if len(ratios) > 1 else float("nan")
    return float(photo.sum() / seen.sum()), spread

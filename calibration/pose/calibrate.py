"""Pose and field of view of a scene photograph (``workbench calibrate pose``).

The scene file's camera is the starting guess; the scene's known 3D edges
(calibration.pose.scene_model: the Cornell box's creases and open front, the ceiling light's
rectangle, each CD's rim) are projected with the camera model (renderer.camera, OpenCV's
pinhole with radial-tangential distortion) and aligned with the photo's edges in three
stages:

1. **Coarse** (nlopt, BOBYQA: [Powell 2009]): the
   truncated chamfer cost of the projected edge points against the photo's Canny edges
   (calibration.pose.edges.ChamferMap), coarse to fine over image scales, so that a start tens
   of pixels off still lands in the right basin. Unknowns: the 6 pose parameters, and,
   without intrinsics, the focal length and the principal point.
2. **Fine**: sub-pixel edge positions along each projected edge's normal
   (calibration.pose.edges.edge_offsets), then robust (Huber) least squares of the
   point-to-edge distances over the same unknowns (+ k1 without intrinsics), with the
   analytic Jacobian of cv2.projectPoints; repeated with shrinking search windows until
   the projection stops moving (the "moving edges" scheme of [Harris 1992] and
   [Drummond 2002, Eqs. 3-6]). With intrinsics given they are held fixed. Then the test that
   can say no: the share of the scene's projected edges the photo shows at the fitted camera
   (``coverage``, calibration.pose.edge_fit.edge_coverage; 0.92-0.99 on photos of the scene, 0.25-0.62
   on photos of chessboards and a colour chart) must reach MIN_COVERAGE (0.75), else the photo is
   refused as not showing the scene, before anything renders. pose.json records it.
3. **Render check** (renderer.rerender.FitRenderer: the scene rendered with the fitted camera,
   fixed seed): the photometric scale (exposure x light power) is the ratio of the photo
   to the render over the walls, and the render, scaled, clipped, mosaicked and
   demosaicked like the photo, is measured by the same edge finder at the same points:
   what it finds there is the finder's own bias (shading across a crease, blur, clipping
   at the light), which is subtracted from the photo's offsets before a last fine fit
   (analysis by synthesis). It is rendered in passes of a few samples per pixel until the
   noise measured between them no longer matters (calibration.pose.render_check: the
   scale to 0.1 %, the pose to a third of its stated std; at most ``render_spp``).
4. **CD fringes** (calibration.pose.fringe_rotation, ``PoseSettings.cd_fringes``): with the walls'
   scale known, the photo's CD against re-renders cropped to the disc, over the camera's
   rotation (nlopt BOBYQA, fixed seed). A check by default: its suggested rotation and
   residuals go to the outputs; ``cd_fringes_apply`` takes the step only within a guard
   (see that module for why it is not applied: measured, it does not beat the edges).

Uncertainties: the covariance of the fine fit, s^2 (J^T W J)^-1, with W the Huber weights
and s^2 their weighted residual variance (Gauss-Newton approximation of the cost's
curvature), plus what a systematic offset, tilt or bow of each edge (the edge finder's
residual bias, >= 0.02 px) and the uncertainty of intrinsics held fixed do to the
solution (first-order propagation), plus, with intrinsics free, the spread of restarts.
Residuals are reported in pixels, per feature. Measured on the draft synthetic dataset
(tests/calibration/test_pose.py): with board intrinsics, 0.055-0.06 deg and 0.25-0.3 mm,
most of it the board's principal point (1 px off in cy); with the true intrinsics,
0.008-0.013 deg and 0.04-0.2 mm. Without intrinsics one photo of the box leaves the
principal point, tilt and focal length weakly determined (0.3-0.5 deg, 3-6 mm, 0.1-0.2 deg
of FOV), which ``std`` says.
"""

from __future__ import annotations

import time
from pathlib import Path

from tqdm import tqdm

from calibration.pose.edge_fit import FREE_RADIAL_TERMS, PoseSettings, Unknowns, coarse_fit
from calibration.pose.inputs import fit_renderer, load_intrinsics, load_inverse_response, start_camera
from calibration.pose.outputs import PHOTOMETRY_NOTE, POSE_FORMAT, result_json, versions, write_outputs
from calibration.pose.photo import read_photo
from calibration.pose.scene_model import scene_model
from calibration.pose.stages import check_photo, fit_photo
from renderer.scene import load_scene

# The module's layout: the edge fit in pose_fit, its uncertainties in pose_uncertainty, one
# photo's stages in pose_photo, the render check in pose_render_check, what is read in
# pose_inputs and what is written in pose_outputs; this module is the command, and the names the command line and tests use.
__all__ = ["PoseSettings", "Unknowns", "calibrate_pose", "coarse_fit", "fit_photo", "fit_renderer", "load_intrinsics",
           "start_camera"]


def calibrate_pose(photo_path: str | Path, scene: str | Path, out: str | Path | None = None, *,
                   intrinsics: str | Path | None = None, response: str | Path | None = None,
                   settings: PoseSettings | None = None, progress: bool = True) -> dict:
    """``workbench calibrate pose``: fit one photo; write OUT/pose.json and OUT/fitted_scene.toml.

    Without ``intrinsics`` the focal length (fx, fy with the scene's ratio), the principal
    point and k1, k2 are fitted too; a single photo of the box constrains them weakly (see
    ``std``). ``response`` linearises a non-raw photo. Returns pose.json's content."""
    started = time.perf_counter()
    settings = settings or PoseSettings()
    spec = load_scene(scene)
    known = load_intrinsics(intrinsics) if intrinsics is not None else None
    inverse = load_inverse_response(response) if response is not None else None
    photo = read_photo(photo_path, inverse)
    check_photo(photo)
    start = start_camera(spec, photo, known)
    unknowns = Unknowns(intrinsics=known is None, radial=FREE_RADIAL_TERMS if known is None else 0)
    bar = tqdm(total=3, desc="calibrate pose", unit="stage", disable=not progress)
    renderer = fit_renderer(spec, start, settings.render_spp) if settings.render_check else None
    result = fit_photo(photo, scene_model(spec), start, unknowns, settings, renderer, bar,
                       known["std"] if known else None)
    bar.close()
    record = {"format": POSE_FORMAT, "command": "workbench calibrate pose", "scene": str(scene),
              "intrinsics": known["source"] if known else None, "response": str(response) if response else None,
              **result_json(result), "light_power_scale": 1.0,
              "photometry": PHOTOMETRY_NOTE, "linear": photo.linear, "settings": settings.to_json(), "versions": versions()}
    record["timings"] = result.timings | {"total_s": time.perf_counter() - started}
    if out is not None:
        write_outputs(Path(out), "pose.json", record, spec, result.camera, result.exposure_scale)
    return record

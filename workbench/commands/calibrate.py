"""``workbench calibrate intrinsics|response|pose|DATASET``: camera calibration from photographs (calibration)::

    workbench calibrate intrinsics IMAGE... --board COLSxROWS --square-mm S [--charuco DICT,MARKER_MM]
                                   --out intrinsics.json [--model auto|pinhole|rational|fisheye|omnidir]
                                   [--fit-k3] [--no-tangential] [--quiet]
    workbench calibrate response IMAGE... [--times T,...] --out response.json
    workbench calibrate pose PHOTO --scene SCENE [--intrinsics intrinsics.json] [--response response.json] --out DIR
    workbench calibrate DATASET --scene SCENE --out DIR [--board COLSxROWS] [--square-mm S]

Each step is one entry of :data:`CALIBRATE_STEPS` (a function adding its parser, one running
it). ``calibrate DATASET`` reads the board of DATASET/calibration/ from its board.json
(calibration.board.board_file); ``--board`` and ``--square-mm`` override it (the run says so). It
names a folder where the other steps name a subcommand: ``route_dataset`` rewrites such a
command line to ``calibrate dataset DATASET ...`` before argparse sees it
(``calibrate dataset DATASET`` works as well).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2

from calibration.board.charuco import parse_charuco
from calibration.intrinsics.calibrate import calibrate_board_views, write_intrinsics
from calibration.intrinsics.lens_models import MODEL_CHOICES
from workbench.commands.arguments import board_argument, exposure_times_argument, positive_number
from workbench.core.files import exclusive_output

if TYPE_CHECKING:  # calibration.pose.calibrate pulls in the renderer and scipy: imported where a pose is fitted
    from calibration.pose.calibrate import PoseSettings

POSE_SCENE_HELP = "the scene the photos show: a built-in scene (`workbench list scenes`) or a scene file"
DATASET_STEP = "dataset"


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add the ``calibrate`` group, one subcommand per step of :data:`CALIBRATE_STEPS`."""
    calibrate = commands.add_parser("calibrate", help="camera calibration from photographs")
    steps = calibrate.add_subparsers(dest="calibrate_command", required=True)
    for add, _ in CALIBRATE_STEPS.values():
        add(steps)


def run(args: argparse.Namespace) -> int:
    return CALIBRATE_STEPS[args.calibrate_command][1](args)


# ---------------------------------------------------------------- intrinsics


def add_intrinsics(steps: argparse._SubParsersAction) -> None:
    p = steps.add_parser("intrinsics", help="focal lengths, principal point and distortion from board views")
    p.add_argument("images", nargs="+", metavar="IMAGE", help="board photographs (raw, JPEG, PNG, TIFF), one camera")
    p.add_argument("--board", type=board_argument, required=True, metavar="COLSxROWS",
                   help="inner corners of a checkerboard (e.g. 9x6); with --charuco, the board's squares")
    p.add_argument("--square-mm", type=positive_number(float), required=True, metavar="S", help="side of a square, mm")
    p.add_argument("--charuco", metavar="DICT,MARKER_MM", help="a ChArUco board: OpenCV dictionary and marker side, "
                   "e.g. DICT_5X5_100,15 (default: a plain checkerboard)")
    p.add_argument("--out", required=True, metavar="intrinsics.json",
                   help="fx, fy, cx, cy, distortion with standard deviations, per-view errors, settings")
    p.add_argument("--model", choices=MODEL_CHOICES, default="auto",
                   help="the lens model: pinhole (OpenCV's k1, k2, p1, p2, k3), rational (k1..k6, p1, p2), fisheye "
                        "(Kannala-Brandt k1..k4), omnidir (Mei: xi, k1, k2, p1, p2), or auto: the simplest model whose "
                        "held-out-view RMS no richer model beats (default: auto)")
    p.add_argument("--fit-k3", action="store_true", help="pinhole: let k3 be fitted too where the held-out views "
                   "support it (default: held at 0)")
    p.add_argument("--no-tangential", action="store_true",
                   help="hold the tangential terms p1, p2 at 0 (OpenCV's CALIB_ZERO_TANGENT_DIST): radial distortion "
                        "only, as calibrations that report no tangential terms use (default: fitted where the held-out "
                        "views support them)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


IMAGE_CORNERS = ("top_left", "top_right", "bottom_left", "bottom_right")


def _px(value: float | None) -> str:
    return "no ray" if value is None else f"{value:.2f}"


def corners_text(s: dict) -> str:
    """The largest projection uncertainty over the image corners that have a ray (a fisheye's corners may lie
    beyond its image circle: no ray, None in the record), and how many have none."""
    known = [s[k] for k in IMAGE_CORNERS if s.get(k) is not None]
    if not known:
        largest = s.get("max")
        return "no ray through any image corner" + (f" (largest over the image {largest:.2f} px)"
                                                    if largest is not None else "")
    text = f"corners up to {max(known):.2f} px"
    if len(known) < len(IMAGE_CORNERS):
        text += f" ({len(IMAGE_CORNERS) - len(known)} of {len(IMAGE_CORNERS)} corners have no ray)"
    return text


def uncertainty_line(record: dict) -> str:
    """intrinsics.json's projection uncertainty and cross-validation diff in one line.

    (calibration.intrinsics.projection_uncertainty)
    """
    unc, cross = record.get("projection_uncertainty"), record.get("cross_validation") or {}
    if not unc:
        return "projection uncertainty: not computed"
    s = unc["std_px"]
    line = (f"projection uncertainty (worst direction, rays at infinity): centre {_px(s.get('centre'))}, median "
            f"{_px(s.get('median'))}, {corners_text(s)}; ")
    if "diff_px" not in cross:
        return line + f"no cross-validation: {cross.get('skipped')}"
    return line + (f"cross-validation diff median {cross['diff_px']['median']:.2f} px against "
                   f"{cross['predicted_px']['median']:.2f} predicted (pooled ratio {cross['splits']['pooled_ratio']:.2f})")


def run_intrinsics(args: argparse.Namespace) -> int:
    charuco = parse_charuco(args.charuco) if args.charuco else None
    flags = (0 if args.fit_k3 else cv2.CALIB_FIX_K3) | (cv2.CALIB_ZERO_TANGENT_DIST if args.no_tangential else 0)
    with exclusive_output(args.out, "calibrate"):
        result = calibrate_board_views(args.images, args.board, args.square_mm / 1000.0, flags=flags, charuco=charuco,
                                       progress=not args.quiet, model=args.model)
        settings = {"board": list(args.board), "board_counts": "squares" if charuco else "inner corners",
                    "square_mm": args.square_mm, "charuco": None if charuco is None else
                    {"dictionary": charuco.dictionary, "marker_mm": charuco.marker_size_m * 1e3},
                    "model": args.model, "images": [str(p) for p in args.images]}
        record = write_intrinsics(result, args.out, settings)
    used = [v for v in result.views if v.used]
    std = record["std"]
    warned = f"; warning: {'; '.join(record['warnings'])}" if record["warnings"] else ""
    print(f"wrote {args.out}: {record['width']} x {record['height']}, {len(used)} of {len(result.views)} views used, "
          f"RMS {record['rms_px']:.3f} px{warned}")
    print(f"fx {record['fx']:.2f} +- {std['fx']:.2f}, fy {record['fy']:.2f} +- {std['fy']:.2f}, "
          f"cx {record['cx']:.2f} +- {std['cx']:.2f}, cy {record['cy']:.2f} +- {std['cy']:.2f} px; "
          f"dist {', '.join(f'{d:.4g}' for d in record['dist'])}" + (f", xi {record['xi']:.4g}" if "xi" in record else ""))
    prior = (record.get("priors") or {}).get("principal_point")
    if prior:   # calibration.intrinsics.lens_models.centre_prior
        print(f"priors: principal point at the image centre ({prior['at_px'][0]:.1f}, {prior['at_px'][1]:.1f}) +- "
              f"{prior['std_px'][0]:.1f}, {prior['std_px'][1]:.1f} px, chosen by the held-out views; the stds above "
              "include it")
    choice = record.get("model_choice")
    print(f"model {record['model']}: " + (choice["why"] if choice else "as asked (--model)"))
    if choice and "terms" in choice:   # calibration.intrinsics.lens_choice.choose_terms
        print(f"distortion terms {', '.join(choice['terms']['chosen'])}: {choice['terms']['why']}")
    print(uncertainty_line(record))
    for view in result.views:
        if not view.found:
            print(f"  {Path(view.file).name}: board not found, skipped")
        elif view.note:
            print(f"  {Path(view.file).name}: {view.note}{'' if view.used else ' (not used)'}")
    return 0


# ---------------------------------------------------------------- response


def add_response(steps: argparse._SubParsersAction) -> None:
    p = steps.add_parser("response", help="the camera's response curve from an exposure bracket (raw: a linearity check)",
                         description="Fits the camera's response curve to an exposure bracket of one scene (JPEG, PNG "
                         "or TIFF: a monotone parametric curve fitted with nlopt, with OpenCV's Debevec and Robertson "
                         "curves beside it); a raw bracket is checked for linearity instead. Exposure times come from "
                         "EXIF or --times.")
    p.add_argument("images", nargs="+", metavar="IMAGE", help="the bracket's images, same scene and camera, any order")
    p.add_argument("--times", type=exposure_times_argument, metavar="T,...", help="exposure times in seconds, one per "
                   "image in the order given (default: read from each file's EXIF)")
    p.add_argument("--out", required=True, metavar="response.json", help="the fitted curve and its comparison")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run_response(args: argparse.Namespace) -> int:
    from calibration.response.calibrate import calibrate_response  # deferred: pulls in scipy (start-up time)

    with exclusive_output(args.out, "calibrate"):
        result = calibrate_response(args.images, args.out, times_s=args.times, progress=not args.quiet)
    if result.get("method") == "raw-linearity":
        check = result["linearity"]
        print(f"wrote {args.out}: raw bracket of {len(result['files'])} files, slope of log value against log exposure "
              f"{check['slope']:.4f} ({'linear' if result['linear'] else 'NOT linear'})")
        return 0
    print(f"wrote {args.out}: {result['method']} response curve from {len(result['files'])} images")
    for name, other in result.get("others", {}).items():
        diffs = [c["log_difference"].get("rms") for c in other["channels"].values()]
        shown = ", ".join(f"{d:.3f}" for d in diffs if d is not None)
        print(f"  {name}: RMS log-irradiance difference to it over values 0.05-0.95, per channel: {shown or 'n/a'}")
    for warning in result.get("warnings", []):
        print(f"  warning: {warning}")
    return 0


# ---------------------------------------------------------------- pose, dataset


def _add_fit_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True, metavar="SCENE", help=POSE_SCENE_HELP)
    p.add_argument("--out", required=True, metavar="DIR", help="the results folder (created; files in it are replaced)")
    p.add_argument("--render-spp", type=positive_number(int), default=16, metavar="N",
                   help="at most this many samples per pixel for the render check (exposure x light power, the edge "
                        "finder's bias): it renders passes of 4 and stops once the noise measured between them moves the "
                        "scale by under 0.1 %% and the pose by under a third of its stated std (default: 16)")
    p.add_argument("--no-render-check", action="store_true",
                   help="skip the render check: edges only, no photometry (seconds instead of a minute)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def add_pose(steps: argparse._SubParsersAction) -> None:
    p = steps.add_parser("pose", help="pose and field of view of one scene photo from the scene's known edges",
                         description="Starts from the scene file's camera, aligns the box's edges, the light and the "
                                     "CD's rim with the photo (coarse chamfer, then sub-pixel edges), checks against a "
                                     "render, and writes DIR/pose.json and DIR/fitted_scene.toml.")
    p.add_argument("photo", metavar="PHOTO", help="a raw file (DNG, NEF, CR2, ...) or a JPEG/PNG/TIFF of the scene")
    p.add_argument("--intrinsics", metavar="intrinsics.json",
                   help="hold these intrinsics fixed (`workbench calibrate intrinsics`); without them the focal "
                        "length, principal point and k1, k2 are fitted from the photo alone (weakly constrained; the default)")
    p.add_argument("--response", metavar="response.json",
                   help="inverse response for a non-raw photo (default: none; a JPEG/PNG/TIFF is then used as it is, non-linear)")
    _add_fit_options(p)


def add_dataset(steps: argparse._SubParsersAction) -> None:
    p = steps.add_parser(DATASET_STEP, help="every step on a dataset folder (also: `workbench calibrate DATASET`)",
                         description="Intrinsics from DATASET/calibration/, the response from DATASET/brackets/, the "
                                     "pose of every photo in DATASET/photos/; writes DIR/calibration.json, "
                                     "DIR/fitted_scene.toml, DIR/scenes/*.toml, intrinsics.json and response.json. "
                                     "Never reads truth.json.")
    p.add_argument("dataset", metavar="DATASET", help="a folder with photos/ (and brackets/, calibration/), "
                                                      "as `workbench synth` writes")
    p.add_argument("--board", type=board_argument, default=None, metavar="COLSxROWS",
                   help="inner corners of the checkerboard in calibration/ (ChArUco: its squares); overrides "
                        "calibration/board.json (the default), needed without it")
    p.add_argument("--square-mm", type=positive_number(float), default=None, metavar="S",
                   help="the board's square size in mm; overrides calibration/board.json (the default), needed without it")
    p.add_argument("--model", choices=MODEL_CHOICES, default="auto",
                   help="the board views' lens model, as for `calibrate intrinsics` (default: auto)")
    _add_fit_options(p)


def _pose_settings(args: argparse.Namespace) -> PoseSettings:
    from calibration.pose.calibrate import PoseSettings  # deferred: pulls in the renderer and scipy (start-up time)

    return PoseSettings(render_check=not args.no_render_check, render_spp=args.render_spp)


def run_pose(args: argparse.Namespace) -> int:
    from calibration.pose.calibrate import calibrate_pose  # deferred: pulls in the renderer and scipy (start-up time)

    with exclusive_output(args.out, "calibrate"):
        record = calibrate_pose(args.photo, args.scene, args.out, intrinsics=args.intrinsics, response=args.response,
                                settings=_pose_settings(args), progress=not args.quiet)
    print(pose_summary_line(record["photo"], record))
    print(f"wrote {args.out}/pose.json and {args.out}/fitted_scene.toml in {record['timings']['total_s']:.1f} s")
    return 0


def run_dataset(args: argparse.Namespace) -> int:
    from calibration.dataset import calibrate_dataset, dataset_files, stage_needs  # deferred: start-up time

    for line in stage_needs(dataset_files(args.dataset)):
        print(line)
    with exclusive_output(args.out, "calibrate"):
        record = calibrate_dataset(args.dataset, args.scene, args.out, board=args.board, square_mm=args.square_mm,
                                   settings=_pose_settings(args), progress=not args.quiet, model=args.model)
    camera, std = record["camera"], record["std"]
    board = record["settings"]["board"]
    if board is not None:
        size = board.get("inner_corners", board.get("squares"))
        print(f"board: {board['kind']} {size[0]}x{size[1]}, {board['square_mm']:g} mm squares ({board['source']})")
    print(f"camera: fx {camera['fx']:.2f} +- {std['fx']:.2f}, fy {camera['fy']:.2f} +- {std['fy']:.2f}, "
          f"cx {camera['cx']:.2f} +- {std['cx']:.2f}, cy {camera['cy']:.2f} +- {std['cy']:.2f} px "
          f"(FOV {camera['fov_x_deg']:.3f} deg; {camera['model']} lens; intrinsics: {record['intrinsics']['source']})")
    for name, photo in record["photos"].items():
        print(pose_summary_line(name, photo))
    vignetting = record.get("vignetting") or {}
    print(f"vignetting: {'applied' if vignetting.get('applied') else 'not applied'}: {vignetting.get('why')}")
    print(f"wrote {args.out}/calibration.json and fitted_scene.toml in {record['timings']['total_s']:.1f} s")
    return 0


def pose_summary_line(name: str, photo: dict[str, Any]) -> str:
    """One photo's fitted camera, its uncertainty and residual, in one line."""
    std, residuals = photo["std"], photo["residuals"]
    centre = photo["camera"]["camera_center_m"]
    scale = photo.get("exposure_scale")
    text = (f"{name}: camera at ({centre[0]:.4f}, {centre[1]:.4f}, {centre[2]:.4f}) m "
            f"+- {1000 * max(std['camera_center_m']):.2f} mm, rotation +- {std['rotation_total_deg']:.3f} deg, "
            f"FOV {photo['camera']['fov_x_deg']:.3f} deg, edge residual {residuals['robust_sigma_px']:.2f} px "
            f"({residuals['points']} points)")
    if residuals.get("coverage") is not None:  # the goodness-of-fit test (calibration.pose.edge_fit.edge_coverage)
        text += f", {100 * residuals['coverage']:.0f} % of the scene's edges found"
    if scale is not None:
        text += f", exposure x light {scale:.4g}"
    return text


def route_dataset(argv: Sequence[str], steps: Sequence[str]) -> list[str]:
    """``calibrate DATASET ...`` -> ``calibrate dataset DATASET ...`` when the word after
    the ``calibrate`` command is neither a step (``steps``) nor an option. Only the command
    word counts (top-level options such as ``--cache DIR`` may come before it), so a file
    named ``calibrate`` given to another command is left alone."""
    argv = list(argv)
    i = 0
    while i < len(argv) and argv[i].startswith("-"):
        i += 2 if argv[i] == "--cache" else 1
    if i < len(argv) and argv[i] == "calibrate":
        nxt = i + 1
        if nxt < len(argv) and argv[nxt] not in steps and not argv[nxt].startswith("-"):
            argv.insert(nxt, DATASET_STEP)
    return argv


CALIBRATE_STEPS: dict[str, tuple[Callable[[argparse._SubParsersAction], None], Callable[[argparse.Namespace], int]]] = {
    "intrinsics": (add_intrinsics, run_intrinsics),
    "response": (add_response, run_response),
    "pose": (add_pose, run_pose),
    DATASET_STEP: (add_dataset, run_dataset),
}

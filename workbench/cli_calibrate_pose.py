"""``workbench calibrate pose`` and ``workbench calibrate DATASET`` (calibration.pose, calibration.dataset).

    workbench calibrate pose PHOTO --scene SCENE [--intrinsics intrinsics.json] [--response response.json] --out DIR
    workbench calibrate DATASET --scene SCENE --out DIR [--board COLSxROWS] [--square-mm S]

``calibrate DATASET`` reads the board of DATASET/calibration/ from its board.json
(calibration.board_file); ``--board`` and ``--square-mm`` override it (the run says so).

Two entries for workbench/cli_calibrate.py's CALIBRATE_STEPS (``STEPS``: a function adding
the parser, one running it). ``calibrate DATASET`` names a folder where the other steps
name a subcommand; ``route_dataset`` rewrites such a command line to
``calibrate dataset DATASET ...`` before argparse sees it (``calibrate dataset DATASET``
works as well).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence

from workbench.cli_arguments import board_argument, positive_number

SCENE_HELP = "the scene the photos show: a built-in scene (`workbench list scenes`) or a scene file"
DATASET_STEP = "dataset"


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True, metavar="SCENE", help=SCENE_HELP)
    p.add_argument("--out", required=True, metavar="DIR", help="the results folder (created; files in it are replaced)")
    p.add_argument("--render-spp", type=positive_number(int), default=16, metavar="N",
                   help="samples per pixel of the render check (exposure x light power, the edge finder's bias)")
    p.add_argument("--no-render-check", action="store_true",
                   help="skip the render check: edges only, no photometry (seconds instead of a minute)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def add_pose(steps) -> None:
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
    _add_common(p)


def add_dataset(steps) -> None:
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
    _add_common(p)


def _settings(args: argparse.Namespace):
    from calibration.pose import PoseSettings

    return PoseSettings(render_check=not args.no_render_check, render_spp=args.render_spp)


def run_pose(args: argparse.Namespace) -> int:
    from calibration.pose import calibrate_pose

    record = calibrate_pose(args.photo, args.scene, args.out, intrinsics=args.intrinsics, response=args.response,
                            settings=_settings(args), progress=not args.quiet)
    print(summary_line(record["photo"], record))
    print(f"wrote {args.out}/pose.json and {args.out}/fitted_scene.toml in {record['timings']['total_s']:.1f} s")
    return 0


def run_dataset(args: argparse.Namespace) -> int:
    from calibration.dataset import calibrate_dataset

    record = calibrate_dataset(args.dataset, args.scene, args.out, board=args.board, square_mm=args.square_mm,
                               settings=_settings(args), progress=not args.quiet)
    camera, std = record["camera"], record["std"]
    board = record["settings"]["board"]
    if board is not None:
        size = board.get("inner_corners", board.get("squares"))
        print(f"board: {board['kind']} {size[0]}x{size[1]}, {board['square_mm']:g} mm squares ({board['source']})")
    print(f"camera: fx {camera['fx']:.2f} +- {std['fx']:.2f}, fy {camera['fy']:.2f} +- {std['fy']:.2f}, "
          f"cx {camera['cx']:.2f} +- {std['cx']:.2f}, cy {camera['cy']:.2f} +- {std['cy']:.2f} px "
          f"(FOV {camera['fov_x_deg']:.3f} deg; intrinsics: {record['intrinsics']['source']})")
    for name, photo in record["photos"].items():
        print(summary_line(name, photo))
    print(f"wrote {args.out}/calibration.json and fitted_scene.toml in {record['timings']['total_s']:.1f} s")
    return 0


def summary_line(name: str, photo: dict) -> str:
    std, residuals = photo["std"], photo["residuals"]
    centre = photo["camera"]["camera_center_m"]
    scale = photo.get("exposure_scale")
    text = (f"{name}: camera at ({centre[0]:.4f}, {centre[1]:.4f}, {centre[2]:.4f}) m "
            f"+- {1000 * max(std['camera_center_m']):.2f} mm, rotation +- {std['rotation_total_deg']:.3f} deg, "
            f"FOV {photo['camera']['fov_x_deg']:.3f} deg, edge residual {residuals['robust_sigma_px']:.2f} px "
            f"({residuals['points']} points)")
    if scale is not None:
        text += f", exposure x light {scale:.4g}"
    return text


STEPS: dict[str, tuple[Callable, Callable[[argparse.Namespace], int]]] = {
    "pose": (add_pose, run_pose),
    DATASET_STEP: (add_dataset, run_dataset),
}


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

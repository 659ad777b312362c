"""The calibration commands of the ``workbench`` command line.

    workbench decode FILE --out OUT.exr [--json] [--response response.json] [--demosaic ALG]
    workbench calibrate intrinsics IMAGE... --board COLSxROWS --square-mm S [--charuco DICT,MARKER_MM]
                                   --out intrinsics.json [--fit-k3] [--quiet]
    workbench calibrate response IMAGE... [--times T,...] --out response.json

``calibrate`` is a group: each calibration step is one entry of CALIBRATE_STEPS (a
function adding its parser, one running it), so ``response`` and ``pose`` are added the
same way as ``intrinsics``. workbench/cli.py calls ``add_parsers`` while building its
parser and ``run`` for the commands in COMMANDS; user errors raise UserInputError, which
cli.py prints as ``error: ...`` with exit status 2.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path

from workbench.cli_arguments import board_argument, positive_number
from workbench.cli_calibrate_pose import STEPS as CALIBRATE_POSE_STEPS

COMMANDS = ("decode", "calibrate")


def _add_decode(commands) -> None:
    from calibration.decode import DEMOSAIC_ALGORITHMS

    decode = commands.add_parser("decode", help="a photograph (raw or JPEG/PNG/TIFF) to linear camera RGB (EXR + JSON)")
    decode.add_argument("file", metavar="FILE", help="a raw file LibRaw reads, or an 8/16-bit JPEG, PNG or TIFF")
    decode.add_argument("--out", required=True, metavar="OUT.exr", help="OpenEXR output; OUT.json beside it")
    decode.add_argument("--json", action="store_true", help="print one JSON object instead of a summary")
    decode.add_argument("--response", metavar="response.json",
                        help='inverse response for non-raw images: {"points": [[irradiance, value], ...]} on [0, 1] '
                             '(default: none; a JPEG/PNG/TIFF is then decoded as it is and flagged non-linear)')
    decode.add_argument("--demosaic", choices=DEMOSAIC_ALGORITHMS, default="linear",
                        help="LibRaw demosaicing for raw files (default: linear, i.e. bilinear)")


def _add_intrinsics(steps) -> None:
    p = steps.add_parser("intrinsics", help="focal lengths, principal point and distortion from board views")
    p.add_argument("images", nargs="+", metavar="IMAGE", help="board photographs (raw, JPEG, PNG, TIFF), one camera")
    p.add_argument("--board", type=board_argument, required=True, metavar="COLSxROWS",
                   help="inner corners of a checkerboard (e.g. 9x6); with --charuco, the board's squares")
    p.add_argument("--square-mm", type=positive_number(float), required=True, metavar="S", help="side of a square, mm")
    p.add_argument("--charuco", metavar="DICT,MARKER_MM", help="a ChArUco board: OpenCV dictionary and marker side, "
                   "e.g. DICT_5X5_100,15 (default: a plain checkerboard)")
    p.add_argument("--out", required=True, metavar="intrinsics.json",
                   help="fx, fy, cx, cy, distortion with standard deviations, per-view errors, settings")
    p.add_argument("--fit-k3", action="store_true", help="fit k3 too (default: held at 0)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _run_intrinsics(args: argparse.Namespace) -> int:
    import cv2

    from calibration.charuco import parse_charuco
    from calibration.intrinsics import calibrate_board_views, write_intrinsics

    charuco = parse_charuco(args.charuco) if args.charuco else None
    flags = 0 if args.fit_k3 else cv2.CALIB_FIX_K3
    result = calibrate_board_views(args.images, args.board, args.square_mm / 1000.0, flags=flags, charuco=charuco,
                                   progress=not args.quiet)
    settings = {"board": list(args.board), "board_counts": "squares" if charuco else "inner corners",
                "square_mm": args.square_mm, "charuco": None if charuco is None else
                {"dictionary": charuco.dictionary, "marker_mm": charuco.marker_size_m * 1e3},
                "images": [str(p) for p in args.images]}
    record = write_intrinsics(result, args.out, settings)
    used = [v for v in result.views if v.used]
    std = record["std"]
    print(f"wrote {args.out}: {record['width']} x {record['height']}, {len(used)} of {len(result.views)} views used, "
          f"RMS {record['rms_px']:.3f} px")
    print(f"fx {record['fx']:.2f} +- {std['fx']:.2f}, fy {record['fy']:.2f} +- {std['fy']:.2f}, "
          f"cx {record['cx']:.2f} +- {std['cx']:.2f}, cy {record['cy']:.2f} +- {std['cy']:.2f} px; "
          f"dist {', '.join(f'{d:.4g}' for d in record['dist'])}")
    for view in result.views:
        if not view.found:
            print(f"  {Path(view.file).name}: board not found, skipped")
        elif view.note:
            print(f"  {Path(view.file).name}: {view.note}{'' if view.used else ' (not used)'}")
    return 0


def _run_decode(args: argparse.Namespace) -> int:
    from calibration.decode import decode_to_exr

    record = decode_to_exr(args.file, args.out, response=args.response, demosaic=args.demosaic)
    if args.json:
        keys = ("width", "height", "black_level", "white_level", "cfa", "exposure_time_s", "iso", "make", "model",
                "saturated_fraction", "linear", "source", "demosaic", "channels", "response")
        print(json.dumps({k: record[k] for k in keys}))
        return 0
    exposure = "unknown" if record["exposure_time_s"] is None else f"{record['exposure_time_s']:g} s"
    camera = " ".join(x for x in (record["make"], record["model"]) if x) or "unknown camera"
    print(f"wrote {args.out} and {Path(args.out).with_suffix('.json')}: {record['width']} x {record['height']} "
          f"{record['source']}, {camera}, exposure {exposure}, ISO {record['iso'] or 'unknown'}, "
          f"{100 * record['saturated_fraction']:.2f} % saturated, "
          f"{'linear' if record['linear'] else 'NOT linear (no response given)'}")
    return 0


def _times_argument(text: str) -> list[float]:
    try:
        values = [float(t) for t in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected exposure times in seconds, T,T,... (e.g. 1/250 as 0.004), got {text!r}") from None
    if any(not v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"exposure times must be positive, got {text!r}")
    return values


def _add_response(steps) -> None:
    p = steps.add_parser("response", help="the camera's response curve from an exposure bracket (raw: a linearity check)",
                         description="Fits the camera's response curve to an exposure bracket of one scene (JPEG, PNG "
                         "or TIFF: a monotone parametric curve fitted with nlopt, with OpenCV's Debevec and Robertson "
                         "curves beside it); a raw bracket is checked for linearity instead. Exposure times come from "
                         "EXIF or --times.")
    p.add_argument("images", nargs="+", metavar="IMAGE", help="the bracket's images, same scene and camera, any order")
    p.add_argument("--times", type=_times_argument, metavar="T,...", help="exposure times in seconds, one per image "
                   "in the order given (default: read from each file's EXIF)")
    p.add_argument("--out", required=True, metavar="response.json", help="the fitted curve and its comparison")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _run_response(args: argparse.Namespace) -> int:
    from calibration.response import calibrate_response

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


CALIBRATE_STEPS: dict[str, tuple[Callable, Callable[[argparse.Namespace], int]]] = {
    "intrinsics": (_add_intrinsics, _run_intrinsics),
    "response": (_add_response, _run_response),
}
CALIBRATE_STEPS.update(CALIBRATE_POSE_STEPS)  # calibrate pose, calibrate dataset (workbench/cli_calibrate_pose.py)


def add_parsers(commands) -> None:
    """Add ``decode`` and the ``calibrate`` group to the top-level subparsers."""
    _add_decode(commands)
    calibrate = commands.add_parser("calibrate", help="camera calibration from photographs")
    steps = calibrate.add_subparsers(dest="calibrate_command", required=True)
    for add, _ in CALIBRATE_STEPS.values():
        add(steps)


def run(args: argparse.Namespace) -> int:
    if args.command == "decode":
        return _run_decode(args)
    return CALIBRATE_STEPS[args.calibrate_command][1](args)

"""``workbench report``: compare a photo with a render of the same view (reports.report)."""

from __future__ import annotations

import argparse
from pathlib import Path

from workbench.commands.cache import add_cache_option
from workbench.core.errors import UserInputError
from workbench.core.files import exclusive_output


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench report``."""
    parser = commands.add_parser(
        "report", help="compare a photo with a render of the same view: CD fringe positions, error maps, one HTML page",
        description="Writes DIR/report.html (one self-contained page: A/B flip, synchronised zoom, exposure slider, "
                    "error maps, the CD's band edges against the grating equation), DIR/report.json (every number; "
                    "fringe_offset_px = {median, p95, count} of the photo-render band-edge offsets) and DIR/fringes.csv.")
    parser.add_argument("--photo", required=True, metavar="PHOTO",
                        help="the photo: a raw file (DNG, ...), a linear float image (EXR), or a JPEG/PNG/TIFF when the "
                             "calibration holds a fitted response (decoded by calibration.raw.decode)")
    parser.add_argument("--render", required=True, metavar="RENDER.exr",
                        help="the render made with the calibration's camera (linear camera RGB, `workbench render`)")
    parser.add_argument("--calibration", required=True, metavar="calibration.json",
                        help="the fitted camera: camera = {width, height, fx, fy, cx, cy, dist, world_to_camera: "
                             "{photo file name: 4x4}} (a synthetic dataset's truth.json has this form)")
    parser.add_argument("--scene", required=True, metavar="SCENE", help="the scene (a built-in name or a TOML file)")
    parser.add_argument("--out", required=True, metavar="DIR", help="the report's folder")
    parser.add_argument("--bracket", nargs="+", default=[], metavar="FRAME",
                        help="darker frames of the photo's view (an exposure bracket, raw or linear like the photo): "
                             "the photo's clipped pixels, such as the CD's bright first orders, are taken from them, "
                             "scaled by the exposure ratio measured from the images; default: none")
    parser.add_argument("--study", action="append", default=[], metavar="DIR",
                        help="a folder written by `workbench study ...` whose figures the page shows (repeatable)")
    add_cache_option(parser)


def run(args: argparse.Namespace) -> int:
    from reports.report import Inputs, build_report  # deferred: pulls in scipy and cv2 (start-up time)

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserInputError("is a file, not a folder", field="--out", expected="a folder for the report", got=args.out)
    with exclusive_output(out, "report"):
        report = build_report(Inputs(Path(args.photo), Path(args.render), Path(args.calibration), args.scene, out,
                                     tuple(Path(s) for s in args.study), tuple(Path(b) for b in args.bracket)))
    fo = report.get("fringe_offset_px") or {}
    median, p95 = fo.get("median"), fo.get("p95")
    offsets = (f"fringe offset photo-render: median {median:.2f} px, p95 {p95:.2f} px over {fo.get('count')} band edges"
               if median is not None else "fringe offset: no band edge seen in both images")
    print(f"wrote {out / 'report.html'} ({report['html_bytes'] / 1e6:.1f} MB), report.json and fringes.csv in "
          f"{report['seconds']:.1f} s; {offsets}")
    for problem in report.get("problems", []):
        print(f"warning: {problem}")
    for message in report.get("messages", []):
        print(f"note: {message}")
    return 0

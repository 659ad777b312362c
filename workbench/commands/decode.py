"""``workbench decode FILE --out OUT.exr``: a photograph to linear camera RGB (calibration.raw.decode)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from calibration.raw.decode import DEMOSAIC_ALGORITHMS, decode_to_exr
from workbench.core.files import exclusive_output

SUMMARY_KEYS = ("width", "height", "black_level", "white_level", "cfa", "exposure_time_s", "iso", "make", "model",
                "saturated_fraction", "linear", "source", "demosaic", "channels", "response", "layout",
                "demosaic_reason")  # printed by --json (layout and demosaic_reason: null for a non-raw image)


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench decode``."""
    decode = commands.add_parser("decode", help="a photograph (raw or JPEG/PNG/TIFF) to linear camera RGB (EXR + JSON)")
    decode.add_argument("file", metavar="FILE", help="a raw file LibRaw reads, or an 8/16-bit JPEG, PNG or TIFF")
    decode.add_argument("--out", required=True, metavar="OUT.exr", help="OpenEXR output; OUT.json beside it")
    decode.add_argument("--json", action="store_true", help="print one JSON object instead of a summary")
    decode.add_argument("--response", metavar="response.json",
                        help='inverse response for non-raw images: {"points": [[irradiance, value], ...]} on [0, 1] '
                             '(default: none; a JPEG/PNG/TIFF is then decoded as it is and flagged non-linear)')
    decode.add_argument("--demosaic", choices=DEMOSAIC_ALGORITHMS, default="linear",
                        help="LibRaw demosaicing for raw files (default: linear, i.e. bilinear)")


def run(args: argparse.Namespace) -> int:
    with exclusive_output(args.out, "decode"):
        record = decode_to_exr(args.file, args.out, response=args.response, demosaic=args.demosaic)
    if args.json:
        print(json.dumps({k: record[k] for k in SUMMARY_KEYS}))
        return 0
    exposure = "unknown" if record["exposure_time_s"] is None else f"{record['exposure_time_s']:g} s"
    camera = " ".join(x for x in (record["make"], record["model"]) if x) or "unknown camera"
    print(f"wrote {args.out} and {Path(args.out).with_suffix('.json')}: {record['width']} x {record['height']} "
          f"{record['source']}, {camera}, exposure {exposure}, ISO {record['iso'] or 'unknown'}, "
          f"{100 * record['saturated_fraction']:.2f} % saturated, "
          f"{'linear' if record['linear'] else 'NOT linear (no response given)'}")
    return 0

"""``workbench verify DATASET --scene SCENE --out RUN``: photos to report in one resumable run (workbench.verify)::

    workbench verify DATASET --scene SCENE --out RUN [--preset draft|paper] [--spp N] [--photo NAME]...
                     [--seed N] [--board COLSxROWS] [--square-mm S] [--scheduler ADDRESS | --workers N]
                     [--force] [--quiet]

The run itself, its stages and their folders: workbench/verify.py.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from workbench.commands.arguments import SEED_MAX, board_argument, count_argument, positive_number
from workbench.commands.cache import add_cache_option


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench verify``."""
    verify = commands.add_parser(
        "verify", help="photos to report in one resumable run: plan, tables, calibration, render, fit, report",
        description="Runs plan -> tables -> calibration -> render (every photo with its fitted camera, at the photo's "
                    "size) -> fit (the scene fit and its verdict; the renders measure the forward model's own offsets) "
                    "-> rerender (the fitted scene, after the verdict model) -> report into RUN, one folder per stage. "
                    "Each stage's inputs (file bytes, settings, version) are hashed: a re-run skips finished stages, "
                    "a killed run resumes where it stopped. RUN/run.json records settings, versions, timings and "
                    "keys; the summary gives each report's path, the fringe offsets (median, p95) and the calibration "
                    "residuals. truth.json is never read (see `score`).")
    verify.add_argument("dataset", metavar="DATASET", help="a folder with photos/ (and optionally brackets/, calibration/)")
    verify.add_argument("--scene", required=True, metavar="SCENE",
                        help="the scene the photos show: a built-in scene name or a TOML file")
    verify.add_argument("--out", required=True, metavar="RUN", help="the run's folder (resumed when it holds this run)")
    verify.add_argument("--preset", choices=["draft", "paper"], default="draft",
                        help="draft: draft tables; paper: the paper's tables (2 deg, 31 wavelengths); both render each region "
                             "to what the report measures there (`render --target report`; the frame at most 256 and "
                             "2045 spp)")
    verify.add_argument("--spp", type=count_argument(1), metavar="N",
                        help="render this many samples per pixel everywhere instead (the fixed render: draft 256, paper "
                             "2045; default: each region to what the report needs, render --target report)")
    verify.add_argument("--photo", action="append", default=[], metavar="NAME",
                        help="render and report only this photo of photos/ (repeatable; default: every photo)")
    verify.add_argument("--seed", type=count_argument(0, SEED_MAX), default=0, help="the render's random seed")
    verify.add_argument("--board", type=board_argument, metavar="COLSxROWS",
                        help="inner corners of the checkerboard in calibration/ (default: calibrate DATASET's)")
    verify.add_argument("--square-mm", type=positive_number(float), metavar="S",
                        help="the board's square size (default: calibrate DATASET's)")
    verify.add_argument("--study", action="append", default=[], metavar="DIR",
                        help="a `workbench study` folder: its accuracy-versus-time figures go into each report and the "
                             "run's index (repeatable)")
    verify.add_argument("--scheduler", metavar="ADDRESS",
                        help="run the table chunks, each photo's calibration, the scene fit, the render passes and each "
                             "photo's report as tasks on "
                             "this dask.distributed scheduler (workers see the dataset, RUN and the cache at the same paths; "
                             "default: in this process)")
    verify.add_argument("--workers", type=count_argument(1), metavar="N",
                        help="the same on a local dask cluster of N worker processes (default: none, in this process)")
    verify.add_argument("--force", action="store_true", help="replace another run (or write beside other files) in RUN")
    verify.add_argument("--quiet", action="store_true", help="no progress bars")
    add_cache_option(verify)


def run(args: argparse.Namespace) -> int:
    from workbench.verify import VerifySettings, format_summary, verify  # deferred: pulls in every library (start-up time)

    settings = VerifySettings(preset=args.preset, spp=args.spp, seed=args.seed, photos=tuple(args.photo),
                              board=args.board, square_mm=args.square_mm, scheduler=args.scheduler, workers=args.workers,
                              studies=tuple(str(Path(d).resolve()) for d in args.study),
                              progress=not args.quiet)
    record = verify(args.dataset, args.scene, args.out, settings, force=args.force)
    print(format_summary(record))
    return 0

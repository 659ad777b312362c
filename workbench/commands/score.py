"""``workbench score RUN --truth DATASET/truth.json [--json]``: a verify run against a synthetic dataset's truth
(workbench.score)."""

from __future__ import annotations

import argparse
import json


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench score``."""
    score = commands.add_parser(
        "score", help="a verify run on a synthetic dataset against its truth: calibration errors, fringe offsets",
        description="Compares RUN's calibration with the dataset's truth.json (rotation, camera centre, field of view, "
                    "principal point, exposure x light power, response) and prints them with the fringe offsets; "
                    "writes RUN/score.json.")
    score.add_argument("run", metavar="RUN", help="the --out folder of a `workbench verify` run")
    score.add_argument("--truth", required=True, metavar="truth.json", help="the synthetic dataset's truth.json")
    score.add_argument("--json", action="store_true", help="print score.json instead of the table")


def run(args: argparse.Namespace) -> int:
    from workbench.score import format_score, score_run  # deferred: pulls in calibration, scipy and cv2 (start-up time)

    result = score_run(args.run, args.truth)
    print(json.dumps(result, indent=2) if args.json else format_score(result))
    return 0

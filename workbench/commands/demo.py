"""``workbench demo``: the main job on the built-in defaults (workbench.demo)."""

from __future__ import annotations

import argparse

from workbench.commands.cache import add_cache_option


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench demo``."""
    demo = commands.add_parser("demo", help="the main job on the built-in defaults: a synthetic dataset of cornell_cd, then "
                               "verify and score on it, in out/demo/", description="Writes the default synthetic dataset "
                               "(workbench synth cornell_cd) to out/demo/dataset, runs workbench verify on it (first photo) "
                               "into out/demo/run and scores the calibration against the truth; ends with the report's path.")
    add_cache_option(demo)


def run(args: argparse.Namespace) -> int:
    from workbench.demo import run_demo  # deferred: pulls in every library, scipy and cv2 (start-up time)

    return run_demo()

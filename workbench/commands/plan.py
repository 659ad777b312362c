"""``workbench plan SCENE``: what a scene needs simulated, before anything runs (renderer.trace.planner)."""

from __future__ import annotations

import argparse
import json
import sys

from workbench.commands.arguments import SCENE_HELP


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench plan``."""
    plan = commands.add_parser("plan", help="what a scene needs simulated: tables, orders, angles, wavelengths, cost",
                               description="Reads the scene and decides, before anything runs, which efficiency tables "
                               "its render needs (R, T, which sides), which orders can reach the camera, which part of each "
                               "table's (wavelength, theta, phi) grid the camera's rays can look up, the camera's "
                               "wavelength range, and which glass dispersion matters; with the cost measured here.")
    plan.add_argument("scene", help=SCENE_HELP)
    plan.add_argument("--json", action="store_true", help="print one JSON object instead of the table")


def run(args: argparse.Namespace) -> int:
    from renderer.scene import load_scene  # deferred: as above
    from renderer.trace.planner import format_plan, plan_scene  # deferred: the renderer pulls in scipy and cv2 (start-up time)

    spec = load_scene(args.scene)  # refuses a scene that would render black or miss the box (renderer.scene)
    for warning in spec.warnings:  # legitimate but suspicious: a camera that sees little of the scene
        print(f"warning: {warning}", file=sys.stderr)
    result = plan_scene(spec)
    print(json.dumps(result.to_json(), indent=2) if args.json else format_plan(result))
    return 0

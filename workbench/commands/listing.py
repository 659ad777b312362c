"""``workbench list KIND``: the built-in structures, scenes, materials and cameras (workbench.catalog)."""

from __future__ import annotations

import argparse

from workbench.catalog import KINDS, format_builtins


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench list``."""
    listing = commands.add_parser("list", help="the built-in structures, scenes, materials and cameras")
    listing.add_argument("kind", choices=list(KINDS), help="what to list")


def run(args: argparse.Namespace) -> int:
    print(format_builtins(args.kind))
    return 0

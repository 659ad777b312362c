"""``workbench cache list|clear`` and the ``--cache DIR`` option (workbench.core.cache).

``list`` shows each entry's kind, size, age and state (for tables: complete or
unfinished; ``locked`` while a running build holds it); ``clear`` removes every entry no
running build holds and says which it kept.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from workbench.core import cache
from workbench.core.errors import UserInputError

CACHE_HELP = ("the cache folder for tables and meshes (default: $WORKBENCH_CACHE, else $XDG_CACHE_HOME/workbench, "
              "else ~/.cache/workbench)")


def add_cache_option(parser: argparse.ArgumentParser, *, top_level: bool = False) -> None:
    """``--cache DIR``; on subcommands it does not hide a value given before the subcommand."""
    parser.add_argument("--cache", metavar="DIR", help=CACHE_HELP, default=None if top_level else argparse.SUPPRESS)


def apply_cache_option(args: argparse.Namespace) -> None:
    """Make ``--cache DIR`` this process's cache (and its dask workers')."""
    folder = getattr(args, "cache", None)
    if folder:
        try:
            cache.use_cache_root(folder)
        except NotADirectoryError:
            raise UserInputError("is a file, not a folder", field="--cache", expected="a folder for the cache",
                                 got=folder) from None
        return
    root = cache.cache_root()  # WORKBENCH_CACHE, or the user's cache folder (issue 46, cause 11)
    if root.exists() and not root.is_dir():
        raise UserInputError("names a file, not a folder", field=cache.ENVIRONMENT_VARIABLE
                             if os.environ.get(cache.ENVIRONMENT_VARIABLE) else "the cache folder",
                             expected="a folder for the cache (or --cache DIR)", got=str(root))


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench cache list|clear``."""
    parser = commands.add_parser("cache", help="list or empty the cache of efficiency tables and meshes",
                                 description=f"The cache: {CACHE_HELP}. Entries are named by the content they hold, "
                                             "so every folder you work in shares them.")
    sub = parser.add_subparsers(dest="cache_command", required=True, metavar="ACTION")
    listing = sub.add_parser("list", help="entries with kind, size, age and state (locked: a running build holds it)")
    listing.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    add_cache_option(listing)
    clearing = sub.add_parser("clear", help="remove every entry, except those a running build holds (locked)")
    add_cache_option(clearing)


def run(args: argparse.Namespace) -> int:
    root = cache.cache_root()
    if args.cache_command == "list":
        found = cache.entries(root)
        if args.json:
            print(json.dumps({"cache": str(root), "entries": [_as_json(e) for e in found]}, indent=2))
        else:
            print(format_entries(root, found))
        return 0
    removed, kept = cache.clear(root)
    print(f"{root}: removed {len(removed)} entries ({_size(sum(e.bytes for e in removed))})")
    reading = cache.readers(root)
    for entry in kept:
        print(f"kept {entry.kind}/{entry.name}: " + (f"the cache is read by {reading} running render(s)" if reading
                                                      else "locked by a running build"))
    return 0


def _state(entry: cache.CacheEntry) -> str:
    if entry.locked:
        return "locked"
    if entry.kind == "tables":
        try:
            meta = json.loads((entry.path / "zarr.json").read_text()).get("attributes", {})
        except (OSError, ValueError, AttributeError):
            return "unreadable"
        return "complete" if meta.get("complete") else "unfinished"
    return "ready"


def _as_json(entry: cache.CacheEntry) -> dict[str, object]:
    return {"kind": entry.kind, "name": entry.name, "path": str(entry.path), "bytes": entry.bytes,
            "age_s": round(entry.age_s, 1), "state": _state(entry)}


def format_entries(root: Path, found: list[cache.CacheEntry]) -> str:
    lines = [f"cache: {root}"]
    if not found:
        return lines[0] + " (empty)"
    lines.append(f"{'kind':<7} {'size':>9} {'age':>7}  {'state':<10} name")
    for e in found:
        lines.append(f"{e.kind:<7} {_size(e.bytes):>9} {_age(e.age_s):>7}  {_state(e):<10} {e.name}")
    lines.append(f"{len(found)} entries, {_size(sum(e.bytes for e in found))}")
    return "\n".join(lines)


def _size(n: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n} B"


def _age(seconds: float) -> str:
    for unit, scale in (("d", 86400), ("h", 3600), ("min", 60)):
        if seconds >= scale:
            return f"{seconds / scale:.0f} {unit}"
    return f"{seconds:.0f} s"

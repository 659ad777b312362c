"""``workbench list KIND``: the built-in structures, scenes, materials and cameras (workbench.catalog);
``--export NAME`` copies a built-in scene or structure out as a TOML file a user can edit."""

from __future__ import annotations

import argparse
from pathlib import Path

from workbench.catalog import KINDS, format_builtins
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text

EXPORTABLE = ("scenes", "structures")


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench list``."""
    listing = commands.add_parser("list", help="the built-in structures, scenes, materials and cameras")
    listing.add_argument("kind", choices=list(KINDS), help="what to list")
    listing.add_argument("--export", metavar="NAME",
                         help="write the built-in scene or structure NAME as a TOML file to edit (to --out); default: list only")
    listing.add_argument("--out", type=Path, help="the exported file (default: NAME.toml here)")
    listing.add_argument("--force", action="store_true", help="replace an existing --out file")


def export_text(kind: str, name: str) -> str:
    """The TOML text of the built-in ``name`` of ``kind`` (a scene or a structure), as shipped."""
    if kind == "scenes":
        from renderer.scene import BUILTIN_SCENES, load_scene  # deferred: start-up time

        if name not in BUILTIN_SCENES:
            raise UserInputError("no such built-in scene", field="--export", expected=f"one of {', '.join(BUILTIN_SCENES)}",
                                 got=name)
        return load_scene(name).text
    from rcwa.structure import BUILTIN_STRUCTURES, load_structure

    if name not in BUILTIN_STRUCTURES:
        raise UserInputError("no such built-in structure", field="--export",
                             expected=f"one of {', '.join(BUILTIN_STRUCTURES)}", got=name)
    return load_structure(name).text


def run(args: argparse.Namespace) -> int:
    if args.export is None:
        if args.out is not None or args.force:
            raise UserInputError("goes with --export NAME", field="--out" if args.out is not None else "--force")
        print(format_builtins(args.kind))
        return 0
    if args.kind not in EXPORTABLE:
        raise UserInputError(f"only scenes and structures are files to export, not {args.kind}", field="--export",
                             expected="workbench list scenes --export NAME (or structures)")
    text = export_text(args.kind, args.export)
    out = args.out if args.out is not None else Path(f"{args.export}.toml")
    if out.exists() and not args.force:
        raise UserInputError("the file exists", file=out, expected="another --out, or --force to replace it")
    atomic_write_text(out, text)
    print(f"wrote {out}: the built-in {args.kind[:-1]} {args.export}; edit it and pass its path "
          f"(workbench render {out} ...)")
    return 0

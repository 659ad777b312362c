"""The command line's commands: one module per command (or command group), each with its
parser and its handler.

Every module has ``add_parser(commands)``, which adds its command to the top-level
subparsers, and ``run(args) -> int``, which runs it (a group looks its subcommand up in a
table of its own). :data:`COMMANDS` names them in the order ``workbench --help`` lists them;
workbench.cli builds the parser from it and runs ``COMMANDS[args.command].run(args)``.
Shared argument types and help texts are in ``arguments``; the ``--cache DIR`` option is
``cache``'s. A library a command needs is imported at the top of its module where that is
cheap, and inside ``run`` (with a comment) where it pulls in scipy, cv2 or Mitsuba, so that
``workbench --help`` starts in well under a second.
"""

from __future__ import annotations

import argparse
from typing import Protocol

from workbench.commands import (
    cache,
    calibrate,
    decode,
    demo,
    fit,
    listing,
    plan,
    rcwa,
    render,
    report,
    score,
    study,
    synth,
    verify,
)


class Command(Protocol):
    """What a command module offers (each module of this package is one)."""

    def add_parser(self, commands: argparse._SubParsersAction) -> None: ...

    def run(self, args: argparse.Namespace) -> int: ...


COMMANDS: dict[str, Command] = {
    "rcwa": rcwa,
    "render": render,
    "synth": synth,
    "study": study,
    "demo": demo,
    "plan": plan,
    "list": listing,
    "cache": cache,
    "report": report,
    "decode": decode,
    "calibrate": calibrate,
    "fit": fit,
    "verify": verify,
    "score": score,
}

"""The ``workbench`` command line: the top-level parser and ``main``, a lookup in the table
of commands (workbench.commands, one module per command with its parser and handler).

Every user error ends with ``error: <what, where, expected>`` on stderr and exit status 2,
never a Python traceback. So does a failure of the operating system (a full disk, a read-only
folder, a permission, a path that is not a folder): one line naming the path and what to do.
Ctrl-C ends with one line saying that finished work is kept and how to resume, exit 130 (the
shell's 128 + SIGINT), as git and pip end.
"""

from __future__ import annotations

import argparse
import errno
import signal
import sys
from collections.abc import Sequence
from typing import Any

from workbench import __version__
from workbench.commands import COMMANDS
from workbench.commands.cache import add_cache_option, apply_cache_option
from workbench.commands.calibrate import CALIBRATE_STEPS, route_dataset
from workbench.core.errors import UserInputError

DESCRIPTION = """\
A photograph-validation and calibration workbench for wave-optical rendering: rigorous
diffraction efficiencies of periodic surfaces (RCWA), spectral renders of them in a scene
(Mitsuba 3), synthetic raw photographs with known truth, and camera calibration from
photographs. `workbench list scenes` shows the built-in scenes; `workbench demo` runs the
main job on the defaults. Caches and outputs: see the README."""


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Shows each option's default where it has a meaningful one (not None or False)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        empty = action.default is None or action.default is False or action.default is argparse.SUPPRESS
        if empty or action.default == [] or "default" in text:  # []: a repeatable option given no time
            return text
        if action.option_strings or action.nargs in (argparse.OPTIONAL, argparse.ZERO_OR_MORE):
            return f"{text} (default: %(default)s)"
        return text


class _Parser(argparse.ArgumentParser):
    """Every (sub)command's parser shows defaults and keeps the description's line breaks."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="workbench", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    add_cache_option(parser, top_level=True)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS.values():
        command.add_parser(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # quiet when piped into head or less
    parser = _build_parser()
    args = parser.parse_args(route_dataset(sys.argv[1:] if argv is None else list(argv), tuple(CALIBRATE_STEPS)))
    try:
        apply_cache_option(args)
        return COMMANDS[args.command].run(args)
    except UserInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\ninterrupted: {INTERRUPTED_NOTE}", file=sys.stderr)
        return 130
    except OSError as exc:
        if exc.errno not in OS_FAILURES:
            raise  # not the environment's failure: a bug, whose traceback is wanted
        print(f"error: {os_failure_line(exc)}", file=sys.stderr)
        return 2


INTERRUPTED_NOTE = ("what was finished is kept (table chunks, render passes, verify stages, written files); "
                    "run the same command again to resume")
OS_FAILURES = {
    errno.ENOSPC: "free some space there (or point the output or WORKBENCH_CACHE elsewhere), then run the same "
                  "command again: finished work is kept and resumes",
    errno.EDQUOT: "the disk quota is used up: free some space, then run the same command again to resume",
    errno.EROFS: "the file system is read-only: choose a writable --out (or WORKBENCH_CACHE)",
    errno.EACCES: "permission denied: choose a path you may write (or read), or change its permissions",
    errno.EPERM: "operation not permitted: choose another path",
    errno.ENOTDIR: "a part of the path is a file, not a folder: choose another path",
    errno.EEXIST: "a file stands where a folder must be made: choose another path, or move the file",
    errno.EISDIR: "the path is a folder where a file was expected: name a file",
    errno.ENAMETOOLONG: "the path is too long: choose a shorter name",
    errno.EMFILE: "too many open files: raise the limit (ulimit -n) and run the same command again",
}


def os_failure_line(error: OSError) -> str:
    """One line for an operating-system failure: the path, what failed, what to do."""
    where = error.filename if error.filename is not None else "(no path given)"
    return f"{where}: {error.strerror or error}; {OS_FAILURES.get(error.errno or 0, 'see the message')}"


if __name__ == "__main__":
    sys.exit(main())

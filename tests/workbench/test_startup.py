"""``workbench --help`` starts without Mitsuba or Dr.Jit (issue 24): the command line
builds its whole parser from workbench.commands, and a command's heavy imports wait
until the command runs; choices read from rcwa's registries (which pull in scipy) are
read only when needed, and are exactly the registries' names."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

from rcwa.factorization import FACTORIZATION_RULES
from rcwa.solver import STACK_METHODS
from workbench.cli import _build_parser

HEAVY = ("mitsuba", "drjit")
PROBE = """
import json, sys
import workbench.cli
try:
    workbench.cli.main(["--help"])
except SystemExit:
    pass
print(json.dumps(sorted(sys.modules)))
"""


def test_help_imports_neither_mitsuba_nor_drjit() -> None:
    run = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=120, check=True)
    *_, last = run.stdout.strip().splitlines()
    modules = json.loads(last)
    assert "workbench.commands.rcwa" in modules  # the parser was built from every command module
    loaded = sorted(m for m in modules if m.split(".")[0] in HEAVY)
    assert not loaded, f"workbench --help imported {loaded}"


def _option(parser: argparse.ArgumentParser, path: tuple[str, ...], flag: str) -> argparse.Action:
    for word in path:
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = sub.choices[word]
    return next(a for a in parser._actions if flag in a.option_strings)


def test_choices_are_the_registries_names_in_their_order() -> None:
    """--factorization and --stack offer what rcwa's registries hold, read from them (not restated)."""
    parser = _build_parser()
    for path in (("rcwa", "solve"), ("rcwa", "table")):
        assert list(_option(parser, path, "--factorization").choices) == list(FACTORIZATION_RULES)
    assert list(_option(parser, ("rcwa", "solve"), "--stack").choices) == list(STACK_METHODS)

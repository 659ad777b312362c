"""``workbench --help`` starts without Mitsuba or Dr.Jit (issue 24): the command line
builds its whole parser from workbench.commands, and a command's heavy imports wait
until the command runs."""

from __future__ import annotations

import json
import subprocess
import sys

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

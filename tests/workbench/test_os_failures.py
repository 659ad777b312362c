"""Operating-system failures and Ctrl-C end with one line, never a traceback (issue 46, causes 8, 11, 12).

In-process: a command that meets a full disk, a read-only folder or a file where a folder was
expected ends with ``error: PATH: what; what to do`` and exit 2; Ctrl-C with one line saying what
was kept and how to resume, exit 130. Out of process, with a real command: an ``--out`` below a
file (not a folder) on a real raw file.
"""

from __future__ import annotations

import errno
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from workbench import cli

REAL = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"


def _failing_command(monkeypatch, error: BaseException) -> None:
    def run(args):
        raise error
    monkeypatch.setitem(cli.COMMANDS, "cache", SimpleNamespace(run=run, add_parser=cli.COMMANDS["cache"].add_parser))


@pytest.mark.parametrize(("code", "hint"), [(errno.ENOSPC, "run the same command again"),
                                            (errno.EROFS, "read-only"), (errno.ENOTDIR, "not a folder"),
                                            (errno.EACCES, "permission")])
def test_an_os_failure_is_one_line_naming_the_path(monkeypatch, capsys, code, hint):
    _failing_command(monkeypatch, OSError(code, "system says no", "/out/table.zarr/chunk.7"))
    assert cli.main(["cache", "list"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("error: /out/table.zarr/chunk.7: system says no;") and hint in err


def test_ctrl_c_is_one_line_saying_how_to_resume(monkeypatch, capsys):
    _failing_command(monkeypatch, KeyboardInterrupt())
    assert cli.main(["cache", "list"]) == 130
    err = capsys.readouterr().err.strip()
    assert err.startswith("interrupted:") and "resume" in err and "Traceback" not in err


def test_an_unexpected_os_error_still_shows_its_traceback(monkeypatch):
    """Only the environment's failures are turned into one line; anything else is a bug to see."""
    _failing_command(monkeypatch, OSError(errno.EBADF, "bad file descriptor"))
    with pytest.raises(OSError):
        cli.main(["cache", "list"])


@pytest.mark.skipif(not (REAL / "colorchart.dng").is_file(), reason="../shared/data/real is not beside the checkout")
def test_an_output_below_a_file_is_refused_in_one_line(tmp_path):
    blocker = tmp_path / "afile"
    blocker.write_text("not a folder")
    run = subprocess.run([sys.executable, "-m", "workbench.cli", "decode", str(REAL / "colorchart.dng"),
                          "--out", str(blocker / "x.exr")], capture_output=True, text=True, timeout=300)
    assert run.returncode == 2, run.stderr
    assert "Traceback" not in run.stderr and run.stderr.strip().count("\n") == 0
    assert run.stderr.startswith("error: ") and "afile" in run.stderr

"""One writer per output (issue 46): each command that writes an --out holds its lock
(workbench.core.files.exclusive_output) while it works, so a second run into the same output
is refused in one line, naming it, instead of two processes interleaving their files.

The first run is stood in for by holding the lock here; the second is the command itself,
which must refuse before it reads any input (none of the inputs below exist; calibrate
DATASET lists the dataset's files first, so it gets a folder holding one empty photo)."""

from __future__ import annotations

from pathlib import Path

import pytest

from workbench.cli import main
from workbench.core.files import exclusive_output

COMMANDS = {
    "decode": (["decode", "missing.dng", "--out", "{out}"], "out.exr"),
    "calibrate intrinsics": (["calibrate", "intrinsics", "missing.png", "--board", "9x6", "--square-mm", "20",
                              "--out", "{out}"], "intrinsics.json"),
    "calibrate response": (["calibrate", "response", "a.jpg", "b.jpg", "c.jpg", "--out", "{out}"], "response.json"),
    "calibrate pose": (["calibrate", "pose", "missing.dng", "--scene", "cornell_cd", "--out", "{out}"], "pose"),
    "calibrate DATASET": (["calibrate", "photos-folder", "--scene", "cornell_cd", "--out", "{out}"], "calibrated"),
    "report": (["report", "--photo", "p.dng", "--render", "r.exr", "--calibration", "c.json", "--scene", "cornell_cd",
                "--out", "{out}"], "report"),
    "fit": (["fit", "missing-dataset", "--scene", "cornell_cd", "--calibration", "c.json", "--out", "{out}"], "fit"),
}


@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_second_run_into_a_held_output_is_refused(name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    argv, out_name = COMMANDS[name]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "photos-folder" / "photos").mkdir(parents=True)
    (tmp_path / "photos-folder" / "photos" / "view0.dng").write_bytes(b"")
    out = tmp_path / out_name
    command = name.split()[0]
    with exclusive_output(out, command):
        assert main([a.replace("{out}", str(out)) for a in argv]) == 2
    err = capsys.readouterr().err
    assert f"another {command} is writing this output now" in err and str(out) in err, err
    assert len(err.strip().splitlines()) == 1, err
    # released: the same command now gets past the lock and fails on its missing input instead
    assert main([a.replace("{out}", str(out)) for a in argv]) == 2
    assert "is writing this output now" not in capsys.readouterr().err

"""Atomic writes and file hashes (workbench/core/files.py).

Asserted: a finished write replaces the file and leaves no temporary beside it; a write
that fails, or a process killed half-way through one, leaves the previous file exactly as
it was (the promise tables, renders, meshes and datasets rely on); CSV rows come back with
every key as a column; the SHA-256 read in 1 MiB blocks equals hashlib's over the whole
file. Every comparison is exact: these are bytes, not measurements.
"""

from __future__ import annotations

import csv
import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from workbench.core.files import atomic_write, atomic_write_csv, atomic_write_text, file_sha256

OLD = "the previous, complete content\n"
KILL_WAIT_S = 30.0  # the child signals readiness by creating a file; it starts in ~1 s, so this only catches a hang


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_a_finished_write_replaces_the_file_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "sub" / "out.json"  # the parent folder is created
    atomic_write_text(path, OLD)
    assert atomic_write_text(path, "new\n", sync=True) == path
    assert path.read_text() == "new\n"
    assert _leftovers(path.parent) == []


def test_the_temporary_keeps_the_suffix_for_writers_that_choose_a_format_by_it(tmp_path):
    seen: list[Path] = []

    def write(tmp: Path) -> None:
        seen.append(tmp)
        tmp.write_bytes(b"x")

    atomic_write(tmp_path / "image.exr", write)
    assert seen[0].suffix == ".exr" and seen[0].parent == tmp_path and seen[0].name.startswith(".")


def test_a_failed_write_keeps_the_previous_file(tmp_path):
    path = tmp_path / "table.csv"
    path.write_text(OLD)

    def half_then_fail(tmp: Path) -> None:
        tmp.write_text("half a fi")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        atomic_write(path, half_then_fail)
    assert path.read_text() == OLD
    assert _leftovers(tmp_path) == []


def test_a_killed_writer_leaves_the_previous_file(tmp_path):
    """SIGKILL in the middle of writing: no finally runs, yet the real name keeps its old bytes."""
    path, ready = tmp_path / "render.npy", tmp_path / "ready"
    path.write_text(OLD)
    child = f"""
import time
from pathlib import Path
from workbench.core.files import atomic_write
def slow(tmp):
    tmp.write_text("half a fi")
    Path({str(ready)!r}).touch()
    time.sleep(600)
atomic_write({str(path)!r}, slow)
"""
    proc = subprocess.Popen([sys.executable, "-c", child], cwd=Path(__file__).resolve().parents[3])
    try:
        deadline = time.monotonic() + KILL_WAIT_S
        while not ready.exists():
            assert proc.poll() is None, "the writer exited before it could be killed"
            assert time.monotonic() < deadline, "the writer never started writing"
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()
    assert path.read_text() == OLD


def test_csv_has_every_key_as_a_column(tmp_path):
    rows: list[dict] = [{"b": 1, "a": 0.5}, {"a": 2.0, "c": "x"}]
    atomic_write_csv(tmp_path / "rows.csv", rows)
    with open(tmp_path / "rows.csv", newline="") as f:
        back = list(csv.DictReader(f))
    assert list(back[0]) == ["a", "b", "c"]  # sorted, the union of the rows' keys
    assert back == [{"a": "0.5", "b": "1", "c": ""}, {"a": "2.0", "b": "", "c": "x"}]


def test_sha256_over_several_blocks_equals_hashlib(tmp_path):
    data = os.urandom(3 * (1 << 20) + 17)  # three whole 1 MiB blocks and a short one
    (tmp_path / "blob").write_bytes(data)
    assert file_sha256(tmp_path / "blob") == hashlib.sha256(data).hexdigest()
    (tmp_path / "empty").write_bytes(b"")
    assert file_sha256(tmp_path / "empty") == hashlib.sha256(b"").hexdigest()

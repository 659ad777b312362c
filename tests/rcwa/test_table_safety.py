"""Efficiency tables are safe to share and to reuse: concurrent builders, damaged tables
repaired, failed runs leave nothing behind, --force replaces only a table.

A repaired table must equal the undamaged one exactly (same code, same inputs: the
damaged chunk is computed again), so comparisons are exact.
"""

import json
import subprocess
import sys

import numpy as np
import pytest

import rcwa
from rcwa.table import build_table, open_table, settings_for
from tests.rcwa.helpers import damage_chunk
from workbench.cli import main
from workbench.core.errors import UserInputError

# Each builder process prints its build report and a hash of the finished table's arrays.
BUILDER = """
import hashlib, json, sys
import rcwa
from rcwa.table import build_table, open_table, settings_for
s = rcwa.load_structure("cd")
st = settings_for(s, "draft", wavelengths="400:700:4", orders=31, theta_step=3.0, phi_step=5.0)
report = build_table(s, st, sys.argv[1], progress=False, threads=1)
table = open_table(sys.argv[1])
digest = hashlib.sha256(b"".join(table.arrays[n].tobytes() for n in sorted(table.arrays))).hexdigest()
print(json.dumps({"computed": report.chunks_computed, "cached": report.cached, "sha256": digest}))
"""

# Holds a table's lock over a half-written folder, as a builder does while it writes the store, then gives up (its
# run failed) and leaves the folder empty.
HOLDER = """
import pathlib, shutil, sys, time
from workbench.core.cache import entry_lock
out = pathlib.Path(sys.argv[1])
with entry_lock(out):
    print("held", flush=True)
    time.sleep(1.5)
    for child in out.iterdir():
        shutil.rmtree(child) if child.is_dir() else child.unlink()
"""


def _small(structure, **kw):
    args = dict(wavelengths="450:650:3", theta_step=30.0, phi_step=30.0, orders=21, keep=7)
    args.update(kw)
    return settings_for(structure, "draft", **args)


def test_two_processes_building_one_table_both_succeed_with_the_same_table(tmp_path):
    """Started together, one process builds (about 4 s on one thread) while the other waits
    on the table's lock, says so, and then reuses the finished table: both exit 0 and see
    the same arrays. Without the lock the second wrote into the first's half-built store
    (a FileNotFoundError inside zarr)."""
    out = tmp_path / "shared.zarr"
    procs = [subprocess.Popen([sys.executable, "-c", BUILDER, str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(2)]
    results = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [err for _, err in results]
    reports = [json.loads(stdout.strip().splitlines()[-1]) for stdout, _ in results]
    assert sorted(r["computed"] for r in reports) == [0, 4]  # one built all four chunks, the other none
    assert reports[0]["sha256"] == reports[1]["sha256"]
    assert sum("waiting for another process" in err for _, err in results) == 1  # they did overlap


def test_a_half_written_table_under_another_builders_lock_is_waited_for(tmp_path):
    """While a builder holds the lock, its folder is half-written (zarr's group file before our metadata): another
    builder must wait and judge the folder once the lock is free, not refuse it as a different table at once (CI
    saw that race between the two builders above)."""
    out = tmp_path / "t.zarr"
    out.mkdir()
    (out / "zarr.json").write_text(json.dumps({"zarr_format": 3, "node_type": "group", "attributes": {}}))
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(out)], stdout=subprocess.PIPE, text=True)
    assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
    s = rcwa.load_structure("cd")
    report = build_table(s, _small(s), out, progress=False)
    assert holder.wait(timeout=60) == 0
    assert report.chunks_computed == len(_small(s).wavelengths_nm) and open_table(out).meta["complete"]


@pytest.mark.parametrize("damage", ["flip a byte", "truncate", "delete"])
def test_a_damaged_table_is_repaired_when_reused(tmp_path, damage):
    s = rcwa.load_structure("cd")
    st = _small(s)
    out = tmp_path / "d.zarr"
    build_table(s, st, out, progress=False)
    intact = open_table(out).arrays["R"].copy()
    chunk = sorted(p for p in (out / "R" / "c").rglob("*") if p.is_file())[1]
    damage_chunk(chunk, damage)
    with pytest.raises(UserInputError, match=r"chunk 1 \(wavelength 550 nm\).*workbench rcwa table cd --out"):
        open_table(out)  # names the chunk and the command that repairs it
    report = build_table(s, st, out, progress=False)
    assert report.chunks_repaired == [1] and report.chunks_computed == 1 and not report.cached
    assert any("damaged chunk 1 (550 nm)" in note for note in report.notes)
    assert np.array_equal(open_table(out).arrays["R"], intact)


def test_the_command_line_repairs_a_damaged_table_and_says_so(tmp_path, capsys):
    args = ["rcwa", "table", "cd", "--out", str(tmp_path / "c.zarr"), "--preset", "draft", "--wavelengths", "450:650:3",
            "--theta-step", "30", "--phi-step", "30", "--orders", "21", "--keep-orders", "7", "--quiet"]
    assert main(args) == 0
    sorted(p for p in (tmp_path / "c.zarr" / "R" / "c").rglob("*") if p.is_file())[0].unlink()
    capsys.readouterr()
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "up to date" not in out and "computed 1 of 3" in out and "damaged chunk 0 (450 nm)" in out
    assert main(args) == 0 and "up to date" in capsys.readouterr().out


def test_unreadable_metadata_needs_force_and_force_rebuilds(tmp_path):
    s = rcwa.load_structure("cd")
    st = _small(s)
    out = tmp_path / "m.zarr"
    build_table(s, st, out, progress=False)
    intact = open_table(out).arrays["R"].copy()
    (out / "zarr.json").write_text("{ not json")
    with pytest.raises(UserInputError, match="cannot be read.*--force"):
        build_table(s, st, out, progress=False)
    build_table(s, st, out, progress=False, force=True)
    assert np.array_equal(open_table(out).arrays["R"], intact)


def test_damaged_array_metadata_of_the_same_request_is_built_again(tmp_path):
    s = rcwa.load_structure("cd")
    st = _small(s)
    out = tmp_path / "a.zarr"
    build_table(s, st, out, progress=False)
    intact = open_table(out).arrays["R"].copy()
    (out / "R" / "zarr.json").unlink()
    report = build_table(s, st, out, progress=False)
    assert report.chunks_computed == 3 and any("array metadata" in note for note in report.notes)
    assert np.array_equal(open_table(out).arrays["R"], intact)


def test_a_failed_table_run_leaves_nothing_and_the_corrected_run_needs_no_force(tmp_path, capsys):
    """The issue's case: aluminium has no data at 100 nm. Refused before anything is written."""
    out = tmp_path / "t.zarr"
    base = ["rcwa", "table", "cd", "--out", str(out), "--preset", "draft", "--theta-step", "30", "--phi-step", "30",
            "--orders", "21", "--keep-orders", "7", "--quiet"]
    assert main([*base, "--wavelengths", "100:700:11"]) == 2
    err = capsys.readouterr().err
    assert "field 'superstrate'" in err and "--wavelengths" in err and "100 nm" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []  # no zarr.json, no lock file
    assert main([*base, "--wavelengths", "450:650:3"]) == 0


def test_a_build_that_fails_before_a_chunk_is_finished_removes_what_it_created(tmp_path, monkeypatch):
    import rcwa.table.store as table

    def broken(*args, **kwargs):
        raise RuntimeError("solver failure")

    monkeypatch.setattr(table, "compute_chunk", broken)
    s = rcwa.load_structure("cd")
    with pytest.raises(RuntimeError, match="solver failure"):
        build_table(s, _small(s), tmp_path / "f.zarr", progress=False)
    assert list(tmp_path.iterdir()) == []  # neither the table nor its lock file
    (tmp_path / "empty.zarr").mkdir()  # a folder the user made stays, empty
    with pytest.raises(RuntimeError, match="solver failure"):
        build_table(s, _small(s), tmp_path / "empty.zarr", progress=False)
    assert list((tmp_path / "empty.zarr").iterdir()) == []


def test_force_replaces_only_a_table(tmp_path):
    s = rcwa.load_structure("cd")
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "notes.txt").write_text("keep me")
    (folder / "R").mkdir()  # a name a table uses does not make the folder a table
    with pytest.raises(UserInputError, match=r"not part of a table \(notes.txt\)"):
        build_table(s, _small(s), folder, progress=False, force=True)
    assert (folder / "notes.txt").read_text() == "keep me"
    file = tmp_path / "file.zarr"
    file.write_text("x")
    with pytest.raises(UserInputError, match="is a file"):
        build_table(s, _small(s), file, progress=False, force=True)
    assert file.read_text() == "x"
    table = tmp_path / "t.zarr"
    build_table(s, _small(s), table, progress=False)
    report = build_table(s, _small(s, keep=5), table, progress=False, force=True)  # another table: replaced
    assert report.chunks_computed == 3 and open_table(table).meta["settings"]["keep"] == [5]


@pytest.mark.parametrize("garbage", [bytes(range(256)) * 8, b"[" * 100_000, b"[1, 2, 3]"],
                         ids=["random bytes", "deeply nested", "not an object"])
def test_garbage_in_a_tables_metadata_is_refused_in_one_line(tmp_path, capsys, garbage):
    """Issue 46, cause 7: random bytes in zarr.json made `rcwa info`, `rcwa table` and a scene's
    table path end in a UnicodeDecodeError traceback; a deeply nested array in a RecursionError."""
    s = rcwa.load_structure("cd")
    st = _small(s)
    out = tmp_path / "g.zarr"
    build_table(s, st, out, progress=False)
    (out / "zarr.json").write_bytes(garbage)
    (out / "progress.json").write_bytes(garbage)
    assert main(["rcwa", "info", str(out)]) == 2
    assert "not an efficiency table" in capsys.readouterr().err
    with pytest.raises(UserInputError, match="cannot be read.*--force"):
        build_table(s, st, out, progress=False)
    with pytest.raises(UserInputError):
        open_table(out)

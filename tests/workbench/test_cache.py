"""The user's cache (workbench.core.cache, `workbench cache`): where it is, what it lists,
what clear removes and keeps, and that renders in any folder share it.

Every test here points WORKBENCH_CACHE (or XDG_CACHE_HOME, HOME) at its own tmp folder.
"""

import json
import os
from pathlib import Path
from types import SimpleNamespace

import pytest

from workbench.cli import main
from workbench.core import cache


def test_the_cache_folder_follows_flag_then_variable_then_xdg_then_home(tmp_path, monkeypatch):
    monkeypatch.delenv(cache.ENVIRONMENT_VARIABLE, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    assert cache.cache_root() == tmp_path / "home" / ".cache" / "workbench"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/ignored")  # the XDG spec: relative paths are invalid
    assert cache.cache_root() == tmp_path / "home" / ".cache" / "workbench"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_root() == tmp_path / "xdg" / "workbench"
    monkeypatch.setenv(cache.ENVIRONMENT_VARIABLE, str(tmp_path / "env"))
    assert cache.cache_root() == tmp_path / "env"
    cache.use_cache_root(tmp_path / "flag")  # what --cache does (monkeypatch restores the variable)
    assert cache.cache_root() == tmp_path / "flag" and os.environ[cache.ENVIRONMENT_VARIABLE] == str(tmp_path / "flag")


def test_cache_flag_before_or_after_the_command(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(cache.ENVIRONMENT_VARIABLE, str(tmp_path / "env"))
    assert main(["--cache", str(tmp_path / "a"), "cache", "list"]) == 0
    assert f"cache: {tmp_path / 'a'} (empty)" in capsys.readouterr().out
    assert main(["cache", "list", "--cache", str(tmp_path / "b")]) == 0
    assert f"cache: {tmp_path / 'b'} (empty)" in capsys.readouterr().out
    (tmp_path / "file").write_text("x")
    assert main(["--cache", str(tmp_path / "file"), "cache", "list"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "--cache" in err and "Traceback" not in err


def _fill(root: Path) -> None:
    """A finished table, an unfinished one and a mesh, as the renderer leaves them."""
    for name, complete in (("cd-1.zarr", True), ("cd-2.zarr", False)):
        (root / "tables" / name).mkdir(parents=True)
        (root / "tables" / name / "zarr.json").write_text(json.dumps({"attributes": {"complete": complete}}))
        (root / "tables" / name / "progress.json").write_text("{}" + " " * 998)
    (root / "meshes").mkdir()
    (root / "meshes" / "abc.ply").write_text("ply\n" * 100)


NOW = 1_800_000_000.0  # a fixed "now" and file times AGE_S before it: the ages are exact, whatever the clock (issue 23)
AGE_S = 90.0


def _age_files(root: Path, modified: float) -> None:
    for path in [root, *root.rglob("*")]:
        os.utime(path, (modified, modified))


def test_list_shows_kind_size_age_and_state(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(cache.ENVIRONMENT_VARIABLE, str(tmp_path))
    _fill(tmp_path)
    _age_files(tmp_path, NOW - AGE_S)
    monkeypatch.setattr(cache, "time", SimpleNamespace(time=lambda: NOW))  # the cache module's clock only
    with cache.entry_lock(tmp_path / "tables" / "cd-2.zarr"):  # a build in progress
        assert main(["cache", "list", "--json"]) == 0
        data = json.loads(capsys.readouterr().out)
        assert main(["cache", "list"]) == 0
        text = capsys.readouterr().out
    by_name = {e["name"]: e for e in data["entries"]}
    assert data["cache"] == str(tmp_path) and set(by_name) == {"cd-1.zarr", "cd-2.zarr", "abc.ply"}
    assert [by_name[n]["state"] for n in ("cd-1.zarr", "cd-2.zarr", "abc.ply")] == ["complete", "locked", "ready"]
    assert by_name["abc.ply"]["kind"] == "meshes" and by_name["abc.ply"]["bytes"] == 400
    assert by_name["cd-1.zarr"]["bytes"] == len(json.dumps({"attributes": {"complete": True}})) + 1000
    assert [e["age_s"] for e in data["entries"]] == [AGE_S] * 3
    assert "locked" in text and "3 entries" in text and ".lock" not in text


def test_clear_removes_everything_but_what_a_running_build_holds(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(cache.ENVIRONMENT_VARIABLE, str(tmp_path))
    _fill(tmp_path)
    busy = tmp_path / "tables" / "cd-2.zarr"
    with cache.entry_lock(busy):
        assert main(["cache", "clear"]) == 0
        out = capsys.readouterr().out
        assert "removed 2 entries" in out and "kept tables/cd-2.zarr: locked by a running build" in out
        assert busy.is_dir() and not (tmp_path / "tables" / "cd-1.zarr").exists()
        assert list((tmp_path / "meshes").iterdir()) == []
    assert main(["cache", "clear"]) == 0 and "removed 1 entries" in capsys.readouterr().out
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []  # no lock files left either


def test_renders_from_two_folders_share_one_cache_and_write_no_build_folder(tmp_path, monkeypatch):
    """The issue: caches went to ./build in whatever folder a render ran from. Renders from
    two folders now use one table in the cache (the suite's, tests/conftest.py, so the
    table is not built again here) and leave the folders holding only their images."""
    from renderer.render import render

    tables = []
    for folder in ("one", "two"):
        (tmp_path / folder).mkdir()
        monkeypatch.chdir(tmp_path / folder)
        info = render("cornell_cd", "r.exr", spp=4, resolution=(48, 36), progress=False)
        assert sorted(p.name for p in (tmp_path / folder).iterdir()) == ["r.exr", "r.json", "r.png", "r.variance.exr"]
        tables += info["tables"]
    assert len(tables) == 2 and tables[0] == tables[1]
    assert Path(tables[0]).parent == cache.cache_root() / "tables"
    assert cache.cache_root() != Path.home() / ".cache" / "workbench"  # tests/conftest.py keeps the real cache out


@pytest.mark.parametrize("waiting", [False, True])
def test_entry_lock_waits_and_says_so(tmp_path, waiting):
    """A second holder waits for the first; the message comes only when it had to wait."""
    import threading
    import time

    entry = tmp_path / "tables" / "x.zarr"
    messages, order = [], []
    first_has_it = threading.Event()

    def first():
        with cache.entry_lock(entry):
            first_has_it.set()
            time.sleep(0.5 if waiting else 0.0)
            order.append("first done")

    thread = threading.Thread(target=first)
    thread.start()
    first_has_it.wait()
    if not waiting:
        thread.join()
    with cache.entry_lock(entry, notify=messages.append):
        order.append("second in")
    thread.join()
    assert order == ["first done", "second in"]
    assert (len(messages) == 1 and "waiting for another process" in messages[0]) if waiting else messages == []


def test_clear_removes_nothing_while_a_render_reads_the_cache(tmp_path, capsys):
    """Issue 46, cause 5: `cache clear` during a render deleted the meshes the render had just built
    (only a table being built was locked). A render holds a reader's lock (cache.reading) the whole
    time; a reader that died leaves a marker nobody holds, which the next clear removes."""
    import subprocess
    import sys

    from workbench.core import cache

    root = tmp_path / "cache"
    (root / "meshes").mkdir(parents=True)
    mesh = root / "meshes" / "abc.ply"
    mesh.write_text("ply")
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time, pathlib; from workbench.core.cache import reading\n"
        f"with reading(pathlib.Path({str(root)!r})):\n    print('reading', flush=True); time.sleep(20)")],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "reading"
        assert cache.readers(root) == 1
        removed, kept = cache.clear(root)
        assert not removed and [e.name for e in kept] == ["abc.ply"] and mesh.exists()
    finally:
        holder.kill()
        holder.wait()
    assert cache.readers(root) == 0  # the killed reader's marker is stale: removed
    removed, _ = cache.clear(root)
    assert [e.name for e in removed] == ["abc.ply"] and not mesh.exists()


def test_a_cache_variable_naming_a_file_is_refused_in_one_line(tmp_path, monkeypatch, capsys):
    """Issue 46, cause 11: WORKBENCH_CACHE naming a file was a traceback (the --cache flag was checked)."""
    from workbench.cli import main
    from workbench.core.cache import ENVIRONMENT_VARIABLE

    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    monkeypatch.setenv(ENVIRONMENT_VARIABLE, str(afile))
    assert main(["cache", "list"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "WORKBENCH_CACHE" in err and err.strip().count("\n") == 0


@pytest.mark.parametrize("kind", ["folder", "dangling link", "link to a file"])
def test_a_lock_file_that_is_a_folder_or_link_is_refused_by_name(tmp_path, kind):
    """An entry's lock (workbench.core.cache.entry_lock) and an output's (exclusive_output) that are
    a folder or a symbolic link are refused naming the path, not met with EISDIR or ELOOP; a link
    is never followed (the file it names is left as it was)."""
    from workbench.core.cache import entry_lock, lock_path
    from workbench.core.errors import UserInputError
    from workbench.core.files import exclusive_output

    target = tmp_path / "precious.txt"
    target.write_text("keep")
    entry, out = tmp_path / "tables" / "abc.zarr", tmp_path / "out" / "x.exr"
    for lock in (lock_path(entry), out.parent / ".x.exr.render.lock"):
        lock.parent.mkdir(parents=True, exist_ok=True)
        if kind == "folder":
            lock.mkdir()
        else:
            lock.symlink_to(target if kind == "link to a file" else tmp_path / "nowhere")
    with pytest.raises(UserInputError, match="where a lock file belongs") as caught:
        with entry_lock(entry):
            pass
    assert str(lock_path(entry)) in str(caught.value)
    with pytest.raises(UserInputError, match="where a lock file belongs"):
        with exclusive_output(out, "render"):
            pass
    assert target.read_text() == "keep"

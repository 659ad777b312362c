"""`workbench synth` never loses files: --force replaces only a dataset's own files, an
interrupted run leaves the old dataset as it was and resumes from its finished renders,
a failed run leaves nothing behind.

Datasets here are tiny (96 x 72, 2 views and 2 board views at 4 spp, a few seconds each):
these tests are about files. A resumed run must give the uninterrupted run's bytes
exactly (same renders, same seeded noise), so comparisons are exact.
"""

import hashlib
import json

import pytest

import datasets_synthetic.synth as synth_module
from datasets_synthetic.synth import PRESETS, synth
from workbench.cli import main
from workbench.core.errors import UserInputError

TINY = dict(PRESETS["draft"], resolution=(96, 72), views=2, calibration_views=2, spp=4, calibration_spp=4)
FRAMES = TINY["views"] + TINY["calibration_views"]


@pytest.fixture
def tiny(monkeypatch):
    monkeypatch.setitem(PRESETS, "tiny", TINY)
    return dict(preset="tiny", progress=False)


def _contents(folder, skip_run_json=False):
    """Every file by relative path with its SHA-256 (run.json holds timings: left out on request)."""
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in folder.rglob("*") if p.is_file() and not (skip_run_json and p.name == "run.json")}


def test_run_json_lists_every_file_with_size_and_hash(tmp_path, tiny):
    out = tmp_path / "ds"
    synth("cornell_cd", out, seed=1, **tiny)
    listed = json.loads((out / "run.json").read_text())["files"]
    on_disk = _contents(out)
    assert set(listed) == set(on_disk) - {"run.json"}
    assert all(listed[k]["sha256"] == on_disk[k] and listed[k]["bytes"] == (out / k).stat().st_size for k in listed)
    assert [p.name for p in tmp_path.iterdir()] == ["ds"]  # the work folder is gone


def test_force_refuses_foreign_files_and_keeps_them(tmp_path, tiny):
    """The issue's case: a notes.txt and a photos/mine.dng beside a dataset. --force is
    refused, naming both, before anything is rendered; nothing is removed."""
    out = tmp_path / "ds"
    synth("cornell_cd", out, seed=1, **tiny)
    (out / "notes.txt").write_text("my notes")
    (out / "photos" / "mine.dng").write_bytes(b"my photo")
    before = _contents(out)
    with pytest.raises(UserInputError, match=r"not the dataset's \(notes.txt, photos/mine.dng\)"):
        synth("cornell_cd", out, seed=2, force=True, **tiny)
    assert _contents(out) == before
    (out / "notes.txt").unlink()
    (out / "photos" / "mine.dng").unlink()
    (out / "truth.json").write_text("{}")  # a dataset file edited since: not the dataset's any more
    with pytest.raises(UserInputError, match=r"changed since they were written \(truth.json\)"):
        synth("cornell_cd", out, seed=2, force=True, **tiny)


def test_a_folder_of_other_files_is_never_replaced(tmp_path, tiny, monkeypatch, capsys):
    """`--out . --force` in a folder of one's own files: refused with the names, not emptied."""
    (tmp_path / "notes.txt").write_text("keep")
    (tmp_path / "photos").mkdir()
    (tmp_path / "photos" / "mine.dng").write_bytes(b"raw")
    monkeypatch.chdir(tmp_path)
    assert main(["synth", "cornell_cd", "--out", ".", "--force", "--preset", "draft"]) == 2
    err = capsys.readouterr().err
    assert "notes.txt" in err and "photos/mine.dng" in err and "Traceback" not in err
    assert sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*")) == ["notes.txt", "photos",
                                                                                       "photos/mine.dng"]


def test_an_interrupted_run_keeps_the_old_dataset_and_the_rerun_resumes(tmp_path, tiny, monkeypatch):
    """A --force run over dataset A stops after two renders (raised inside the render): A is
    untouched and no half-written dataset sits in its place. The same command then renders
    only the two missing frames and writes exactly the bytes of an uninterrupted run."""
    from renderer.rerender import FitRenderer

    out = tmp_path / "ds"
    synth("cornell_cd", out, seed=1, **tiny)
    old = _contents(out)
    render = FitRenderer.render
    calls = []

    def render_twice_then_stop(self, *args, **kwargs):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(1)
        return render(self, *args, **kwargs)

    monkeypatch.setattr(FitRenderer, "render", render_twice_then_stop)
    with pytest.raises(KeyboardInterrupt):
        synth("cornell_cd", out, seed=2, force=True, **tiny)
    assert _contents(out) == old
    work = tmp_path / f".ds{synth_module.WORK_SUFFIX}"
    assert sorted(p.name for p in (work / "renders").iterdir()) == ["view0.npy", "view1.npy"]
    assert not (work / "dataset").exists()

    calls.clear()  # no limit now: count the renders the rerun does
    monkeypatch.setattr(FitRenderer, "render", lambda self, *a, **k: calls.append(1) or render(self, *a, **k))
    synth("cornell_cd", out, seed=2, force=True, **tiny)
    assert len(calls) == FRAMES - 2
    assert json.loads((out / "run.json").read_text())["resumed_renders"] == 2
    assert not work.exists()
    synth("cornell_cd", tmp_path / "clean", seed=2, **tiny)
    assert _contents(out, skip_run_json=True) == _contents(tmp_path / "clean", skip_run_json=True)


def test_a_failed_run_leaves_nothing_behind(tmp_path, tiny):
    """A scene whose table cannot be built (aluminium has no data at 100 nm) fails before
    the first render: no dataset folder, no empty subfolders, no work folder."""
    from renderer.scene import load_scene

    text = load_scene("cornell_cd").text.replace('table = { preset = "draft" }',
                                                 'table = { preset = "draft", wavelengths = "100:700:7" }')
    scene = tmp_path / "bad.toml"
    scene.write_text(text)
    with pytest.raises(UserInputError, match="100 nm"):
        synth(str(scene), tmp_path / "ds", seed=1, **tiny)
    assert [p.name for p in tmp_path.iterdir()] == ["bad.toml"]


def test_an_interrupted_move_into_place_is_undone_on_the_next_run(tmp_path):
    """The last step swaps the old dataset's entries for the new ones; a crash in between
    is undone (the old dataset comes back whole) before the next run looks at the folder."""
    out, work = tmp_path / "ds", tmp_path / f".ds{synth_module.WORK_SUFFIX}"
    (out / "photos").mkdir(parents=True)
    (out / "photos" / "view0.dng").write_bytes(b"old photo")
    (out / "run.json").write_text("old run")
    staging = work / "dataset"
    (staging / "photos").mkdir(parents=True)
    (staging / "photos" / "view0.dng").write_bytes(b"new photo")
    (staging / "truth.json").write_text("new truth")
    (staging / "run.json").write_text("new run")
    renames = []
    real_rename = synth_module.os.rename

    def crash_after_four(src, dst):
        if len(renames) == 4:  # old photos/ and run.json moved aside, new photos/ and truth.json moved in
            raise KeyboardInterrupt
        renames.append((src, dst))
        real_rename(src, dst)

    synth_module.os.rename = crash_after_four
    try:
        with pytest.raises(KeyboardInterrupt):
            synth_module._move_into_place(staging, out, work)
    finally:
        synth_module.os.rename = real_rename
    assert not (out / "run.json").exists()  # caught half-way
    synth_module._restore_interrupted_swap(out, work)
    assert _contents(out) == {"photos/view0.dng": hashlib.sha256(b"old photo").hexdigest(),
                              "run.json": hashlib.sha256(b"old run").hexdigest()}


def test_a_dataset_from_before_file_lists_is_replaced_only_with_force(tmp_path, tiny):
    """Datasets written before run.json listed its files (out/demo/dataset of an earlier
    demo) are recognised by their truth.json and their layout; an extra file still blocks."""
    out = tmp_path / "old"
    (out / "photos").mkdir(parents=True)
    (out / "photos" / "view0.dng").write_bytes(b"old raw")
    (out / "truth.json").write_text(json.dumps({"format": synth_module.MARKER}))
    (out / "run.json").write_text(json.dumps({"command": "workbench synth"}))
    with pytest.raises(UserInputError, match="holds another dataset"):
        synth("cornell_cd", out, seed=1, **tiny)
    (out / "notes.txt").write_text("mine")
    with pytest.raises(UserInputError, match="no dataset of this workbench listed"):
        synth("cornell_cd", out, seed=1, force=True, **tiny)
    (out / "notes.txt").unlink()
    synth("cornell_cd", out, seed=1, force=True, **tiny)
    assert "files" in json.loads((out / "run.json").read_text()) and (out / "photos" / "view1.dng").is_file()


def test_the_largest_seed_makes_a_dataset(tmp_path, tiny):
    """--seed reaches 2**32 - 1; frame seeds stay inside Mitsuba's 32 bits (before, seeds
    above 4294967 ended in a TypeError inside Mitsuba's sampler)."""
    truth = synth("cornell_cd", tmp_path / "ds", seed=2**32 - 1, **tiny)
    assert truth["seed"] == 2**32 - 1 and (tmp_path / "ds" / "calibration" / "board01.dng").is_file()

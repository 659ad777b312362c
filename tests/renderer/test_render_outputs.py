"""`workbench render` treats its outputs as `rcwa table` treats tables: the finished
identical request is served at once, a different one needs --force, an interrupted one
resumes and says so; and a scene may name a table built with `workbench rcwa table`.

Renders are tiny (48 x 36, a few spp): these tests are about files, not images. A served
or resumed render must equal the uninterrupted one exactly (same passes, same seeds).
"""

import json

import numpy as np
import pytest

from renderer.render import render, summary, variance_path
from workbench.cli import main
from workbench.core.errors import UserInputError

TINY = dict(spp=4, resolution=(48, 36), progress=False)


def _exr(path):
    import mitsuba as mi

    return np.array(mi.Bitmap(str(path)))


def test_identical_request_is_served_and_a_different_one_needs_force(mitsuba_variant, tmp_path):
    out = tmp_path / "r.exr"
    first = render("cornell_cd", out, **TINY)
    stamp = out.stat().st_mtime_ns
    again = render("cornell_cd", out, **TINY)
    assert again["served"] and not first["served"] and out.stat().st_mtime_ns == stamp  # nothing rewritten
    assert "up to date" in summary(again) and "nothing rendered" in summary(again)
    with pytest.raises(UserInputError, match="different render.*--force"):
        render("cornell_cd", out, **(TINY | {"spp": 8}))
    assert out.stat().st_mtime_ns == stamp  # refused before anything was written
    replaced = render("cornell_cd", out, force=True, **(TINY | {"spp": 8}))
    assert replaced["spp"] == 8 and json.loads(out.with_suffix(".json").read_text())["spp"] == 8


def test_a_changed_or_foreign_output_is_not_overwritten_without_force(mitsuba_variant, tmp_path):
    """Files no render wrote are not replaced even with --force (issue 46, cause 3): --force replaces
    only what a render wrote; a render's EXR edited since is replaced with --force only."""
    out = tmp_path / "mine.exr"
    out.write_bytes(b"my own file")
    out.with_suffix(".png").write_bytes(b"my own preview")
    for force in (False, True):
        with pytest.raises(UserInputError, match="no render of this workbench described: mine.exr, mine.png"):
            render("cornell_cd", out, force=force, **TINY)
    assert out.read_bytes() == b"my own file" and out.with_suffix(".png").read_bytes() == b"my own preview"
    out.unlink()
    out.with_suffix(".png").unlink()
    render("cornell_cd", out, **TINY)
    render("cornell_cd", out, force=True, **(TINY | {"spp": 8}))  # a render's own files: --force replaces them
    with open(out, "ab") as f:  # edited after the render: no longer the finished request
        f.write(b"\0")
    with pytest.raises(UserInputError, match="EXR was changed"):
        render("cornell_cd", out, **TINY)


def test_an_interrupted_render_resumes_and_says_so(mitsuba_variant, tmp_path, monkeypatch):
    """Four passes of 32 spp; the run stops after saving the first. The same command then
    renders only the other three and gives the uninterrupted image (and variance) exactly."""
    import renderer.render as module

    settings = TINY | {"spp": 128}
    clean = render("cornell_cd", tmp_path / "clean.exr", **settings)
    assert clean["passes"] == 4
    save = module.atomic_write_npz
    calls = []

    def save_then_stop(*args, **kwargs):
        save(*args, **kwargs)
        calls.append(1)
        raise KeyboardInterrupt

    monkeypatch.setattr(module, "atomic_write_npz", save_then_stop)
    with pytest.raises(KeyboardInterrupt):
        render("cornell_cd", tmp_path / "r.exr", **settings)
    monkeypatch.setattr(module, "atomic_write_npz", save)
    assert not (tmp_path / "r.exr").exists() and (tmp_path / "r.exr.partial.npz").exists()
    info = render("cornell_cd", tmp_path / "r.exr", **settings)
    assert info["resumed_passes"] == 1 and "resumed after 1 of 4 passes" in summary(info)
    assert np.array_equal(_exr(tmp_path / "r.exr"), _exr(tmp_path / "clean.exr"))
    assert np.array_equal(_exr(variance_path(tmp_path / "r.exr")), _exr(variance_path(tmp_path / "clean.exr")))
    assert not (tmp_path / "r.exr.partial.npz").exists()


def test_the_command_line_has_force_and_reports_a_served_render(mitsuba_variant, tmp_path, capsys):
    args = ["render", "cornell_cd", "--out", str(tmp_path / "c.exr"), "--spp", "4", "--resolution", "48x36", "--quiet"]
    assert main(args) == 0
    capsys.readouterr()
    assert main(args) == 0 and "up to date" in capsys.readouterr().out
    assert main([*args[:-1], "--spp", "8", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "--force" in err and "Traceback" not in err
    assert main([*args, "--spp", "8", "--force"]) == 0


def _scene_with_table(tmp_path, table_line: str):
    from renderer.scene import load_scene

    text = load_scene("cornell_cd").text
    assert 'table = { preset = "draft" }' in text
    path = tmp_path / "scene.toml"
    path.write_text(text.replace('table = { preset = "draft" }', table_line))
    return path


def test_a_scene_can_name_a_table_built_with_rcwa_table(mitsuba_variant, tmp_path, cd_table):
    """The CD's table is the one the scene names (relative to the scene file): no cache
    table is built or looked up for it, and the render uses it."""
    import shutil

    import mitsuba as mi

    from renderer.mitsuba_scene import scene_dict
    from renderer.scene import load_scene

    shutil.copytree(cd_table.path, tmp_path / "mine.zarr")
    spec = load_scene(_scene_with_table(tmp_path, 'table = { path = "mine.zarr" }'))
    _, built = scene_dict(mi, spec, spp=1)
    assert built["tables"] == [str(tmp_path / "mine.zarr")]
    info = render(str(tmp_path / "scene.toml"), tmp_path / "r.exr", **TINY)
    assert info["tables"] == [str(tmp_path / "mine.zarr")]


def test_a_named_table_must_exist_be_intact_and_match_the_structure(mitsuba_variant, tmp_path, cd_table):
    import shutil

    import mitsuba as mi

    import rcwa
    from rcwa.table import build_table, settings_for
    from renderer.mitsuba_scene import scene_dict
    from renderer.scene import load_scene

    missing = r"scene.toml: field 'cd\[0\].table.path'.*nope.zarr.*not an efficiency table"
    with pytest.raises(UserInputError, match=missing):
        scene_dict(mi, load_scene(_scene_with_table(tmp_path, 'table = { path = "nope.zarr" }')), spp=1)

    thicker = rcwa.load_structure("cd").text.replace("thickness = 0.11", "thickness = 0.12")
    other = rcwa.Structure.from_toml_string(thicker, source="thicker.toml")
    assert other.text != rcwa.load_structure("cd").text
    build_table(other, settings_for(other, "draft", wavelengths="380:780:3", theta_step=45.0, phi_step=45.0, orders=11,
                                    keep=5), tmp_path / "other.zarr", progress=False)
    with pytest.raises(UserInputError, match=r"cd\[0\].table.path.*another structure \(thicker.toml\)"):
        scene_dict(mi, load_scene(_scene_with_table(tmp_path, 'table = { path = "other.zarr" }')), spp=1)

    shutil.copytree(cd_table.path, tmp_path / "damaged.zarr")
    sorted(p for p in (tmp_path / "damaged.zarr" / "R" / "c").rglob("*") if p.is_file())[2].unlink()
    with pytest.raises(UserInputError, match=r"cd\[0\].table.path.*chunk 2 .*damaged or missing"):
        scene_dict(mi, load_scene(_scene_with_table(tmp_path, 'table = { path = "damaged.zarr" }')), spp=1)


def test_the_largest_seed_the_command_line_takes_renders(mitsuba_variant, tmp_path):
    """--seed reaches 2**32 - 1; each pass's seed stays inside Mitsuba's 32 bits (before,
    seeds above 42949 ended in a TypeError inside Mitsuba's sampler)."""
    from renderer.render import pass_seed

    info = render("cornell_cd", tmp_path / "s.exr", seed=2**32 - 1, **TINY)
    assert info["seed"] == 2**32 - 1 and np.all(np.isfinite(_exr(tmp_path / "s.exr")))
    assert pass_seed(3, 1) == 3 * 100_003 + 1  # small seeds keep their passes' seeds (and images)


VARIANCE_PAIRS = 6  # independent pairs of renders pooled: fireflies make one pair's ratio swing 0.5-1.2
VARIANCE_RATIO_BOUNDS = (0.7, 1.4)  # pooled ratio measured 0.89, 1.01, 1.05, 0.95 over four sets (SD ~0.07)


def test_the_passes_variance_predicts_how_far_two_renders_differ(mitsuba_variant, tmp_path):
    """Two renders with different seeds differ, pixel by pixel, by var_a + var_b in the mean
    (their noises are independent): the variance files written from the spread between
    passes must predict the summed squared difference, pooled over pairs."""
    squared, predicted = 0.0, 0.0
    for k in range(VARIANCE_PAIRS):
        images, variances = [], []
        for j in (0, 1):
            out = tmp_path / f"r{k}{j}.exr"
            info = render("cornell_cd", out, spp=16, resolution=(96, 72), progress=False, seed=2 * k + j)
            assert info["passes"] == 4 and info["variance"] == str(variance_path(out))
            images.append(_exr(out))
            variances.append(_exr(variance_path(out)))
        squared += float(np.sum((images[0] - images[1]) ** 2))
        predicted += float(np.sum(variances[0] + variances[1]))
    assert VARIANCE_RATIO_BOUNDS[0] < squared / predicted < VARIANCE_RATIO_BOUNDS[1]


def test_one_pass_writes_no_variance(mitsuba_variant, tmp_path):
    info = render("cornell_cd", tmp_path / "r.exr", spp=1, resolution=(48, 36), progress=False)
    assert info["passes"] == 1 and info["variance"] is None and not variance_path(tmp_path / "r.exr").exists()


@pytest.mark.parametrize("damage", ["truncated", "garbage"])
def test_a_damaged_checkpoint_is_removed_and_its_passes_rendered_again(mitsuba_variant, tmp_path, capsys, damage):
    """Issue 46, cause 6: a truncated OUT.exr.partial.npz blocked every rerun with a BadZipFile
    traceback (--force included). Now it is named, removed, and the render equals an uninterrupted one."""
    clean = tmp_path / "clean.exr"
    render("cornell_cd", clean, **TINY)
    out = tmp_path / "r.exr"
    partial = tmp_path / "r.exr.partial.npz"
    np.savez(partial, total=np.zeros(3), total_sq=np.zeros(3), done=1, key="x")
    data = partial.read_bytes()
    partial.write_bytes(data[: len(data) // 2] if damage == "truncated" else bytes(range(256)) * 4)
    info = render("cornell_cd", out, **TINY)
    assert "damaged checkpoint" in capsys.readouterr().err and not partial.exists()
    assert info["resumed_passes"] == 0 and np.array_equal(_exr(out), _exr(clean))


def test_a_second_render_into_the_same_output_at_once_is_refused(mitsuba_variant, tmp_path):
    """Issue 46, cause 4: two different renders into one --out both exited 0, one replacing the other.
    The render holds its output's lock (workbench.core.files.exclusive_output) while it runs."""
    import subprocess
    import sys
    import time

    out = tmp_path / "q.exr"
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time; from workbench.core.files import exclusive_output\n"
        f"with exclusive_output({str(out)!r}, 'render'):\n    print('held', flush=True); time.sleep(20)")],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        started = time.monotonic()
        with pytest.raises(UserInputError, match="another render is writing this output now"):
            render("cornell_cd", out, **TINY)
        assert time.monotonic() - started < 10 and not out.exists()  # refused at once, nothing written
    finally:
        holder.kill()
        holder.wait()
    render("cornell_cd", out, **TINY)  # the lock dies with its process

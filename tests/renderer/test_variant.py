"""Finding libLLVM and setting Mitsuba's variant (renderer/variant.py)."""

import subprocess
import sys

import pytest

from renderer import variant


def _libs(tmp_path, names):
    for n in names:
        (tmp_path / n).write_bytes(b"")
    return (str(tmp_path / "libLLVM*.so*"),)


def test_newest_usable_llvm_is_chosen_and_15_is_skipped(tmp_path):
    globs = _libs(tmp_path, ["libLLVM-15.so", "libLLVM-14.so.1", "libLLVM-19.so", "libLLVM.so.17.0"])
    assert variant.find_libllvm(globs, environ={}).endswith("libLLVM-19.so")
    only_old = tmp_path / "old"
    only_old.mkdir()
    assert variant.find_libllvm(_libs(only_old, ["libLLVM-15.so", "libLLVM-14.so"]), environ={}) is None


def test_explicit_path_wins_when_it_exists(tmp_path):
    globs = _libs(tmp_path, ["libLLVM-19.so"])
    mine = tmp_path / "custom-llvm.so"
    mine.write_bytes(b"")
    assert variant.find_libllvm(globs, environ={"DRJIT_LIBLLVM_PATH": str(mine)}) == str(mine)
    assert variant.find_libllvm(globs, environ={"DRJIT_LIBLLVM_PATH": "/nonexistent"}).endswith("libLLVM-19.so")


@pytest.mark.parametrize("name, major", [("libLLVM-19.so", 19), ("libLLVM.so.19.1", 19), ("libLLVM-15.so.1", 15)])
def test_version_from_file_name(name, major):
    assert variant.llvm_major(name) == major


def _run(code: str, env_extra: dict | None = None) -> subprocess.CompletedProcess:
    import os

    env = dict(os.environ, **(env_extra or {}))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)


def test_llvm_spectral_variant_renders_here():
    """`make install` provides libllvm19, so the fast variant must start and render."""
    proc = _run(
        "from renderer.variant import set_variant; v = set_variant(); import mitsuba as mi;"
        "img = mi.render(mi.load_dict(mi.cornell_box()), spp=4); import numpy as np;"
        "a = np.array(img); print(v, a.shape, bool(np.isfinite(a).all()), float(a.mean()) > 0)"
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split()[0] == "llvm_ad_spectral" and "True True" in proc.stdout


def test_fallback_to_scalar_with_one_warning():
    """Without libLLVM the scalar spectral variant is used, with one warning."""
    proc = _run(
        "import logging; logging.basicConfig();"
        "import renderer.variant as v; v.SEARCH_GLOBS = ();"
        "print(v.set_variant()); print(v.set_variant())",
        {"DRJIT_LIBLLVM_PATH": ""},
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["scalar_spectral", "scalar_spectral"]
    assert proc.stderr.count("no usable libLLVM") == 1


_RENDER_DIGEST = (
    "from renderer.variant import set_variant; set_variant(); import mitsuba as mi, drjit as dr, hashlib;"
    "from renderer.accuracy import element_crop, load_cropped, timed_render;"
    "from renderer.render import with_resolution; from renderer.scene import load_scene;"
    "spec = with_resolution(load_scene('cornell_cd'), (160, 120)); crop, _ = element_crop(mi, spec);"
    "img, _ = timed_render(mi, load_cropped(mi, spec, 'improved', crop), seed=3, spp=16);"
    "print(dr.thread_count(), hashlib.sha256(img.tobytes()).hexdigest())"
)


def test_render_threads_are_pinned_and_a_pinned_render_repeats_its_bytes():
    """WORKBENCH_RENDER_THREADS sets Dr.Jit's pool (the suite pins it: tests/conftest.py), and the
    workbench's renders (box filter: each sample lands in one pixel) then give the same bytes
    run after run; other pool sizes sum in another order (measured on this crop at 64 spp: 1,
    3, 4 and 8 threads give four different digests, each repeatable), which is why it is
    pinned. (Mitsuba's own cornell_box example, with a Gaussian filter whose splats overlap
    between threads, is not repeatable even with the pool pinned.)"""
    runs = [_run(_RENDER_DIGEST, {variant.THREADS_VARIABLE: "3"}) for _ in range(2)]
    for proc in runs:
        assert proc.returncode == 0, proc.stderr
    threads, digests = zip(*(proc.stdout.split() for proc in runs), strict=True)
    assert threads == ("3", "3")
    assert digests[0] == digests[1]


@pytest.mark.parametrize("text", ["0", "-2", "two", "1.5"])
def test_a_bad_render_thread_count_is_refused_by_name(text):
    with pytest.raises(variant.UserInputError, match="whole number") as info:
        variant._pin_threads({variant.THREADS_VARIABLE: text})
    assert info.value.field == variant.THREADS_VARIABLE


def test_no_pin_without_the_variable():
    assert variant._pin_threads({}) is None

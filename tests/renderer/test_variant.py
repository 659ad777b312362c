"""Finding libLLVM and setting Mitsuba's variant (renderer/variant.py)."""

import subprocess
import sys

import numpy as np
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


_RENDER_CROP = (
    "from renderer.variant import set_variant; set_variant(); import mitsuba as mi, drjit as dr, sys;"
    "from renderer.accuracy import element_crop, load_cropped, timed_render;"
    "from renderer.render import with_resolution; from renderer.scene import load_scene;"
    "spec = with_resolution(load_scene('cornell_cd'), (160, 120)); crop, _ = element_crop(mi, spec);"
    "img, _ = timed_render(mi, load_cropped(mi, spec, 'improved', crop), seed=3, spp=16);"
    "print(dr.thread_count()); sys.stdout.flush(); sys.stdout.buffer.write(img.astype('<f4').tobytes())"
)


def _render_crop(threads: str) -> tuple[str, np.ndarray]:
    import os

    env = dict(os.environ, **{variant.THREADS_VARIABLE: threads})
    proc = subprocess.run([sys.executable, "-c", _RENDER_CROP], capture_output=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr.decode(errors="replace")
    count, _, data = proc.stdout.partition(b"\n")
    return count.decode(), np.frombuffer(data, dtype="<f4")


def test_render_threads_are_pinned_and_change_only_the_order_of_the_sums():
    """WORKBENCH_RENDER_THREADS sets Dr.Jit's pool (the suite pins it: tests/conftest.py). With
    one thread a render's bytes repeat by construction (one worker sums every pixel in sample
    order). With several, each sample is the same (the seed fixes it per sample, not per
    thread) but Dr.Jit's workers add a pixel's samples in the order they finish: a quiet
    machine repeats the bytes, a loaded one may not (CI once gave two digests for two 3-thread
    runs on 2 cores). So a 3-thread render must equal the 1-thread one to float32 rounding of a
    16-term sum (relative 1e-5, against ~16 x 6e-8 for the reordering), never by luck of bytes."""
    one_a, one_b = _render_crop("1"), _render_crop("1")
    three = _render_crop("3")
    assert (one_a[0], three[0]) == ("1", "3")
    assert one_a[1].tobytes() == one_b[1].tobytes()
    assert one_a[1].size == three[1].size and one_a[1].size > 0
    assert np.all(np.isfinite(three[1])) and float(one_a[1].max()) > 0
    np.testing.assert_allclose(three[1], one_a[1], rtol=1e-5, atol=1e-6 * float(one_a[1].max()))


@pytest.mark.parametrize("text", ["0", "-2", "two", "1.5"])
def test_a_bad_render_thread_count_is_refused_by_name(text):
    with pytest.raises(variant.UserInputError, match="whole number") as info:
        variant._pin_threads({variant.THREADS_VARIABLE: text})
    assert info.value.field == variant.THREADS_VARIABLE


def test_no_pin_without_the_variable():
    assert variant._pin_threads({}) is None

"""Choosing Mitsuba's variant, and the libLLVM its LLVM backend needs, in one place.

Mitsuba's ``mi.set_variant`` is process-global, so it is called here and nowhere else
(tests use the same function). drjit 1.5's LLVM backend works with LLVM 19 (Debian's
libllvm19, which ``make`` installs) and crashes with LLVM 15, which Debian 12 also ships;
the workbench therefore looks for libLLVM itself, newest first, skips versions known not
to work, sets ``DRJIT_LIBLLVM_PATH`` before drjit loads, and falls back to the scalar
spectral variant with one clear warning when it finds none.

Dr.Jit's thread pool splits a render's samples into blocks by its size, and a pixel whose
samples fall in two blocks is summed in the order the workers finish: the same seed gives
the same samples on any pool, summed in another order (a cornell_cd crop at 16 spp: 4 of
2652 values differ between 1 and 3 threads, by 2e-8 of the peak). ``WORKBENCH_RENDER_THREADS=N``
pins the pool (the test suite sets it: tests/conftest.py). With N=1 the bytes repeat by
construction; with more, a quiet machine repeats them and a loaded one may differ in the
last bits (seen once on CI, 3 threads on 2 cores). Unset, Dr.Jit uses every core.
"""

from __future__ import annotations

import glob
import logging
import os
import re
from collections.abc import Mapping
from pathlib import Path

from workbench.core.errors import UserInputError

LOG = logging.getLogger("workbench.renderer")

PREFERRED_VARIANT = "llvm_ad_spectral"
FALLBACK_VARIANT = "scalar_spectral"
# drjit 1.5 ran here with LLVM 19 and crashed with LLVM 15 (DESIGN.md, section 5); the
# versions in between are untested, so only 16 and up are tried, newest first.
MIN_LLVM_MAJOR = 16
SEARCH_GLOBS = (
    "/usr/lib/x86_64-linux-gnu/libLLVM-*.so*",
    "/usr/lib/x86_64-linux-gnu/libLLVM.so.*",
    "/usr/lib/aarch64-linux-gnu/libLLVM-*.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM.so.*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
)

THREADS_VARIABLE = "WORKBENCH_RENDER_THREADS"

_chosen: str | None = None


def llvm_major(path: str | Path) -> int | None:
    """LLVM major version from a library file name (libLLVM-19.so, libLLVM.so.19.1)."""
    name = Path(path).name
    match = re.search(r"libLLVM-(\d+)", name) or re.search(r"libLLVM\.so\.(\d+)", name)
    if match is None:
        match = re.search(r"llvm-(\d+)", str(path))
    return int(match.group(1)) if match else None


def find_libllvm(search_globs: tuple[str, ...] | None = None, environ: Mapping[str, str] | None = None) -> str | None:
    """The libLLVM to use: ``DRJIT_LIBLLVM_PATH`` if it names an existing file, else the
    newest LLVM >= MIN_LLVM_MAJOR found by ``search_globs`` (default SEARCH_GLOBS), else None."""
    env = os.environ if environ is None else environ
    search_globs = SEARCH_GLOBS if search_globs is None else search_globs
    given = env.get("DRJIT_LIBLLVM_PATH")
    if given and Path(given).is_file():
        return given
    candidates = []
    for pattern in search_globs:
        for path in glob.glob(pattern):
            major = llvm_major(path)
            if major is not None and major >= MIN_LLVM_MAJOR and Path(path).is_file():
                candidates.append((major, path))
    return max(candidates)[1] if candidates else None


def set_variant(preferred: str = PREFERRED_VARIANT) -> str:
    """Set Mitsuba's variant once for this process and return it.

    LLVM variants need libLLVM; without one, the scalar spectral variant is used and a
    single warning says why and how to fix it.
    """
    global _chosen
    if _chosen is not None:
        return _chosen
    variant = preferred
    if preferred.startswith("llvm"):
        path = find_libllvm()
        if path is None:
            LOG.warning(
                "no usable libLLVM (>= %d) found: rendering falls back to the slower %s variant. "
                "Install Debian's libllvm19 (`make install` does) or set DRJIT_LIBLLVM_PATH.",
                MIN_LLVM_MAJOR, FALLBACK_VARIANT,
            )
            variant = FALLBACK_VARIANT
        else:
            os.environ["DRJIT_LIBLLVM_PATH"] = path
    import mitsuba as mi  # deferred: DRJIT_LIBLLVM_PATH must be set before drjit loads; start-up time

    try:
        mi.set_variant(variant)
    except (ImportError, AttributeError, RuntimeError) as exc:
        if variant == FALLBACK_VARIANT:
            raise
        LOG.warning("Mitsuba's %s variant failed to start (%s); using %s.", variant, exc, FALLBACK_VARIANT)
        variant = FALLBACK_VARIANT
        mi.set_variant(variant)
    _pin_threads()
    _chosen = variant
    return variant


def _pin_threads(environ: Mapping[str, str] | None = None) -> int | None:
    """Dr.Jit's thread count from ``WORKBENCH_RENDER_THREADS``, when set (else left alone)."""
    text = (os.environ if environ is None else environ).get(THREADS_VARIABLE, "").strip()
    if not text:
        return None
    if not text.isdigit() or int(text) < 1:
        raise UserInputError("must be a whole number of threads, 1 or more", field=THREADS_VARIABLE, got=text)
    import drjit as dr  # deferred: start-up time (loaded with mitsuba just before)

    dr.set_thread_count(int(text))
    return int(text)


SPECTRAL_VARIANTS = ("scalar_spectral", "llvm_ad_spectral", "cuda_ad_spectral")  # what renderer.plugins needs


def check_variant(variant: str | None) -> None:
    """Refuse a Mitsuba variant the plugins cannot run in (None: no variant set yet).

    Parameters
    ----------
    variant
        Mitsuba's current variant, as ``mitsuba.variant()`` gives it.

    Raises
    ------
    RuntimeError
        When no variant is set, or it is not one of SPECTRAL_VARIANTS.
    """
    choices = ", ".join(SPECTRAL_VARIANTS)
    if variant is None:
        raise RuntimeError(f"set a Mitsuba variant before registering the workbench's plugins: one of {choices} "
                           "(renderer.variant.set_variant() picks llvm_ad_spectral where libLLVM is found)")
    if variant not in SPECTRAL_VARIANTS:
        raise RuntimeError(f"the workbench's plugins (bwdf, dispersive_dielectric, cospower_area) need a spectral, "
                           f"unpolarized Mitsuba variant: one of {choices}; the current variant is {variant!r} "
                           "(an RGB or mono variant has no wavelengths to read the efficiency tables at)")

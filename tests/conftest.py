"""Suite-wide: the workbench's cache (tables, meshes) never goes to the user's real cache.

WORKBENCH_CACHE points at ``workbench-cache`` in pytest's own temporary root (the parent
of the numbered ``pytest-N`` folders, which pytest rotates; this folder is not rotated),
so the whole suite shares one cache, across runs too, as it shared ``./build/tables``
before the cache moved: the built-in scenes' tables (about 30 s for gold2d's) are built
once. Entries are named by content and checked by checksum when reused (rcwa.table,
renderer.meshes), and concurrent runs are safe (file locks). With ``--basetemp`` the cache
lives inside that folder instead (and starts empty).

Workers. ``make test`` runs the suite on pytest-xdist's workers, one file per worker at a
time (``--dist loadfile``: a module's fixtures are made once). Each worker has its own
``popen-gwN`` temporary folder; ``run_root`` is the run's folder above them, where the
cache and the shared synthetic datasets live, each made by one worker under a file lock
while the others wait for it. Tests that need an empty cache of
their own set WORKBENCH_CACHE to a tmp_path folder with monkeypatch.

Thread counts. Dr.Jit's renders depend on its thread count (renderer/variant.py), so the
suite pins it to RENDER_THREADS through WORKBENCH_RENDER_THREADS, set before any test runs
and inherited by the subprocesses and dask workers tests start: a seed renders the same
bytes on a 2-core CI machine and on a 16-core laptop, loaded or not. OpenBLAS is left to the
user's OPENBLAS_NUM_THREADS (the suite passes with 1 and 2): the RCWA core pins it to one
thread inside its own threads, and the BLAS-dependent thresholds carry margins measured over
thread counts and kernels (docs/testing.md).
"""

import os
from pathlib import Path

import pytest
from filelock import FileLock

from workbench.core.cache import ENVIRONMENT_VARIABLE

RENDER_THREADS = "2"
os.environ.setdefault("WORKBENCH_RENDER_THREADS", RENDER_THREADS)  # a developer's own value wins


def run_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """This run's temporary folder, shared by its xdist workers (each has a ``popen-gwN`` in it)."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


@pytest.fixture(scope="session", autouse=True)
def suite_cache(tmp_path_factory, request):
    root = run_root(tmp_path_factory)
    folder = (root if request.config.option.basetemp else root.parent) / "workbench-cache"
    folder.mkdir(exist_ok=True)
    previous = os.environ.get(ENVIRONMENT_VARIABLE)
    os.environ[ENVIRONMENT_VARIABLE] = str(folder)  # also seen by subprocesses and dask workers started from tests
    yield folder
    if previous is None:
        os.environ.pop(ENVIRONMENT_VARIABLE, None)
    else:
        os.environ[ENVIRONMENT_VARIABLE] = previous


def synthetic_dataset(tmp_path_factory: pytest.TempPathFactory, seed: int, scene: str = "cornell_cd",
                      vignetting: tuple[float, float, float] | None = None) -> Path:
    """`workbench synth SCENE --seed SEED [--vignetting PR,PG,PB]` (draft), made once per test
    run and shared by every module and worker that asks for the same one (each takes 2.5
    minutes on 2 cores). Tests must treat it as read-only."""
    from datasets_synthetic.synth import synth

    lens = "" if vignetting is None else "-vignetting" + "-".join(f"{p:g}" for p in vignetting)
    home = run_root(tmp_path_factory) / f"dataset-{scene}-seed{seed}{lens}"
    home.mkdir(exist_ok=True)
    folder = home / "dataset"
    with FileLock(home / "dataset.lock"):
        if not (folder / "truth.json").exists():
            synth(scene, folder, seed=seed, progress=False, vignetting=vignetting)
    return folder

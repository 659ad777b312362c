"""A verify run's folder (workbench.verify): its record RUN/run.json, each stage's key and
folder, how a stage runs (or is skipped, or resumed) and the lock that keeps a second run out.

A stage's key is the SHA-256 of its input files' bytes, its settings and the workbench
version. A stage runs in ``RUN/.staging/NAME`` (marked with its key) and, once complete,
the folder is moved into place in one rename, carrying the key in ``.stage-key``: a
finished stage is one whose folder holds its current key, and is skipped. A killed run
leaves the staging folder; the next run with the same key keeps it and a changed key
clears it.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text, exclusive_output, file_sha256
from workbench.core.version import __version__ as workbench_version
from workbench.core.version import versions

RUN_FORMAT = "workbench-verify"
STAGES = ("plan", "tables", "calibration", "render", "fit", "rerender", "report")
# spp: the fixed render's samples (``--spp`` sets them), and the targeted render's frame cap; target: the render's
# default mode (renderer.render_target: each region sampled to what the report measures there)
PRESETS: dict[str, dict[str, Any]] = {"draft": {"tables": "draft", "spp": 256, "target": "report"},
                                      "paper": {"tables": "paper", "spp": 2045, "target": "report"}}
KEY_FILE = ".stage-key"  # in a finished stage's folder: the key it was made for
DONE_FILE = ".stage-done"  # in a staging folder whose work finished (moved into place next)
VERSIONED = ("numpy", "scipy", "mitsuba", "drjit", "opencv", "rawpy", "nlopt", "zarr")
OWN_NAMES = (*STAGES, ".staging", "scene.toml", "run.json", "index.html")  # what a run writes in RUN; --force removes only these


@dataclass(frozen=True)
class VerifySettings:
    """What a run is asked to do; ``scheduler`` and ``progress`` change how, not what."""

    preset: str = "draft"
    spp: int | None = None  # render samples per pixel everywhere (default: the preset's target)
    seed: int = 0  # the render's seed
    integrator: str = "path"
    mode: str = "improved"
    photos: tuple[str, ...] = ()  # photo file names to render and report (default: every photo)
    board: tuple[int, int] | None = None  # checkerboard inner corners (default: calibration's)
    square_mm: float | None = None
    studies: tuple[str, ...] = ()  # `workbench study` folders whose figures each report and the index show
    scheduler: str | None = field(default=None, compare=False)  # a dask scheduler's address (workbench.core.executor)
    workers: int | None = field(default=None, compare=False)  # or a LocalCluster of this many worker processes
    progress: bool = field(default=True, compare=False)

    @property
    def study_folders(self) -> tuple[Path, ...]:
        return tuple(Path(folder) for folder in self.studies)

    @property
    def render_spp(self) -> int:
        return int(self.spp if self.spp is not None else PRESETS[self.preset]["spp"])

    @property
    def render_target(self) -> str | None:
        """The render's target (renderer.render_target) unless ``spp`` asks for a fixed render."""
        return PRESETS[self.preset].get("target") if self.spp is None else None

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        data["photos"], data["board"] = list(self.photos), list(self.board) if self.board else None
        data["studies"] = list(self.studies)
        return data | {"render_spp": self.render_spp, "render_target": self.render_target,
                       "table_preset": PRESETS[self.preset]["tables"]}


@dataclass
class Run:
    """The run's folder, its record (run.json) and what every stage reads."""

    root: Path
    record: dict[str, Any]
    dataset: Path
    photos: list[Path]
    size: tuple[int, int]
    settings: VerifySettings
    executor: Any = None

    @property
    def scene(self) -> Path:
        return self.root / "scene.toml"

    def save(self) -> None:
        self.record["updated"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        atomic_write_text(self.root / "run.json", json.dumps(self.record, indent=2) + "\n")


def stage_key(name: str, files: dict[str, Path], settings: dict[str, Any]) -> str:
    """SHA-256 over the stage's name, each input file's name and bytes, its settings and the version."""
    request = {"stage": name, "files": {k: file_sha256(p) for k, p in sorted(files.items())}, "settings": settings,
               "version": workbench_version}
    return hashlib.sha256(json.dumps(request, sort_keys=True).encode()).hexdigest()


def _new_record(identity: dict[str, str], settings: VerifySettings) -> dict[str, Any]:
    return {"format": RUN_FORMAT, "identity": identity, "status": "running", "settings": settings.to_json(),
            "versions": versions(*VERSIONED),
            "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "stages": {}}


def read_record(root: Path) -> dict[str, Any] | None:
    """RUN/run.json when a verify run wrote it, else None."""
    try:
        record = json.loads((root / "run.json").read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and record.get("format") == RUN_FORMAT else None


def _remove_own(root: Path) -> None:
    for name in OWN_NAMES:
        path = root / name
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()


def open_run(root: Path, identity: dict[str, str], settings: VerifySettings, force: bool) -> dict[str, Any]:
    """The record to carry on with: this run's (resumed), or a new one. Another run's folder,
    or a folder of files no run wrote, is refused unless ``force``."""
    if root.exists() and not root.is_dir():
        raise UserInputError("is a file, not a folder", field="--out", expected="a folder for the run", got=str(root))
    root.mkdir(parents=True, exist_ok=True)
    record = read_record(root)
    if record is None and (root / "run.json").exists() and all(p.name in OWN_NAMES for p in root.iterdir()):
        # a damaged run.json (issue 46, cause 9) in a folder only a run wrote: a new record, and the stage
        # folders kept, so every stage whose key file matches its inputs and settings is reused, not recomputed
        print(f"note: {root / 'run.json'} could not be read; the run starts a new record and reuses every stage "
              "whose key still matches", file=sys.stderr)
        return _new_record(identity, settings)
    if record is None:
        present = sorted(p.name for p in root.iterdir())
        if present and not force:
            raise UserInputError(f"the folder holds files no verify run wrote: {', '.join(present[:6])}"
                                 f"{' ...' if len(present) > 6 else ''}", file=root,
                                 expected="a new or empty folder, or --force to write the run beside them")
        _remove_own(root)
        return _new_record(identity, settings)
    if record.get("identity") != identity:
        if not force:
            other = record.get("identity", {})
            raise UserInputError(f"the folder holds another run (dataset {other.get('dataset')}, scene "
                                 f"{other.get('scene')})", file=root / "run.json", field="identity",
                                 expected=f"a run of dataset {identity['dataset']} with scene {identity['scene']}, "
                                 "a new folder, or --force to replace it")
        _remove_own(root)
        return _new_record(identity, settings)
    record.update(status="running", settings=settings.to_json())
    record["versions"] = versions(*VERSIONED)
    return record


def _clear(path: Path) -> None:
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()


def _marker(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None


def run_stage(run: Run, name: str, inputs: dict[str, Path], settings: dict[str, Any], estimate_s: float,
              work: Callable[[Path], dict[str, Any]], intact: Callable[[Path], bool] = lambda folder: True) -> dict:
    """Run one stage unless its folder already holds its key (see the module's docstring); returns
    the stage's entry in run.json."""
    key = stage_key(name, inputs, settings)
    final, staging = run.root / name, run.root / ".staging" / name
    entry = run.record["stages"].setdefault(name, {})
    if _marker(final / KEY_FILE) == key and (final / "stage.json").is_file() and intact(final):
        entry.update(status="done", key=key, skipped=True, result=json.loads((final / "stage.json").read_text()))
        run.save()
        _say(run, f"{name}: up to date (key {key[:12]}), skipped")
        return entry
    if _marker(staging / KEY_FILE) != key:
        _clear(staging)  # another key's work, or none: start afresh
    resumed = staging.is_dir()
    staging.mkdir(parents=True, exist_ok=True)
    atomic_write_text(staging / KEY_FILE, key)
    entry.clear()
    entry.update(status="running", key=key, estimate_s=round(estimate_s, 1), resumed=resumed,
                 inputs=sorted(inputs), settings=settings)
    run.save()
    _say(run, f"{name}: {'resuming' if resumed else 'running'} (estimate ~{_duration(estimate_s)})")
    started = time.perf_counter()
    submitted = getattr(run.executor, "submitted", 0)
    if _marker(staging / DONE_FILE) == key:
        result = json.loads((staging / "stage.json").read_text())
    else:
        result = work(staging)
        atomic_write_text(staging / "stage.json", json.dumps(result, indent=2, default=str) + "\n")
        atomic_write_text(staging / DONE_FILE, key)
    _move_into_place(staging, final)
    entry.update(status="done", seconds=round(time.perf_counter() - started, 2), skipped=False, result=result)
    if run.executor is not None:  # what ran on the dask cluster (workbench.core.executor)
        entry["dask_tasks"] = run.executor.submitted - submitted
    run.save()
    return entry


def _move_into_place(staging: Path, final: Path) -> None:
    """The finished staging folder becomes RUN/NAME in one rename (an older one is moved aside first)."""
    old = staging.with_name(staging.name + ".old")
    _clear(old)
    if final.exists():
        os.replace(final, old)
    os.replace(staging, final)
    (final / DONE_FILE).unlink(missing_ok=True)
    _clear(old)


def _say(run: Run, message: str) -> None:
    if run.settings.progress:
        tqdm.write(f"verify: {message}")


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


@contextmanager
def run_lock(root: Path) -> Iterator[None]:
    """One verify run at a time in RUN: an ``flock`` (filelock) on ``.RUN.verify.lock`` beside it, taken without
    waiting; a second run into the same folder is refused while the first holds it."""
    with exclusive_output(root, "verify", "another verify run is writing into this folder now"):
        yield

"""The table on disk: building, resuming and repairing it under its lock.

Storage: a zarr v3 directory store, one chunk per wavelength, float32. A chunk counts as
written only once its SHA-256 is in ``progress.json`` (replaced atomically after each
chunk), so a killed build resumes from its finished chunks and a truncated or altered
table is detected (checksums) instead of read as data. The request's content hash
(rcwa.table.settings.request_key) names what a table holds; asking again for a finished
table returns it at once, after checking every chunk against its checksum: damaged
chunks are computed again.

Safety: the request is validated (settings, the materials' data over the wavelengths)
before anything is written; a build that fails before finishing a chunk removes what it
created; ``force`` replaces only a table (a folder holding nothing but a table's files),
never anything else. A build holds the table's file lock (workbench.core.cache), so a
second process asking for the same table waits and then reuses it.

Truncation error (rcwa.table.truncation): each chunk's record (a few nodes solved again at
a lower truncation and, in 2D, with the other factorization rule) is computed with the
chunk and checkpointed in the same progress.json entry, so a resumed build keeps the
finished chunks' records; chunks finished by a build from before records existed get
theirs when the build resumes. A finished table holds them all in ``truncation_error``
(by chunk index); a table finished before lacks it (read as not recorded).
"""

from __future__ import annotations

import hashlib
import json
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rcwa.factorization import resolve_rule
from rcwa.structure import Structure
from rcwa.sweep import default_threads
from rcwa.table.compute import compute_chunk
from rcwa.table.settings import (
    FORMAT_VERSION,
    GRAZING_THETA_DEG,
    NodePlan,
    TableSettings,
    check_materials,
    kept_indices,
    pol_names,
    request_key,
    symmetry_for,
    transmits,
)
from rcwa.table.truncation import estimate_truncation
from workbench.core.cache import entry_lock, is_locked
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text
from workbench.core.timing import timed
from workbench.core.version import __version__ as workbench_version
from workbench.core.version import versions

ARRAY_NAMES = ("R", "T", "R_below", "T_below")
PLANNED_NODES = "planned_nodes"  # a planned table's mask of exactly solved nodes (wavelength, theta, phi)
TABLE_FILES = ("zarr.json", "progress.json", PLANNED_NODES) + ARRAY_NAMES  # everything a table folder holds


@dataclass
class BuildReport:
    path: Path
    key: str
    chunks_total: int
    chunks_computed: int
    chunks_reused: int
    seconds: float
    cached: bool = False
    symmetry: str = ""
    bytes_on_disk: int = 0
    notes: list[str] = field(default_factory=list)
    eigen_solves: int = 0    # 1D layers' eigen-solves in the chunks computed now
    eigen_refined: int = 0   # of which refined from a neighbouring k_x (rcwa/cpp/sweep.hpp)
    sector_points: int = 0   # directions solved in mirror-symmetry sectors (2D cells: rcwa/cpp/sectors.hpp)
    chunks_repaired: list[int] = field(default_factory=list)  # damaged chunks found and computed again


def build_table(structure: Structure, settings: TableSettings, out: str | Path, *, threads: int | None = None,
                progress: bool = True, force: bool = False, executor=None,
                notify: Callable[[str], None] | None = None, nodes: NodePlan | None = None) -> BuildReport:
    """Build (or resume, or repair, or return the finished) table at ``out``.

    ``nodes``: a planned table's NodePlan (``settings`` from ``planned(settings, nodes)``).

    ``executor``: an object with ``submit(fn, *args)`` returning futures (a
    dask.distributed Client); by default chunks run here on ``threads`` threads.
    ``force`` replaces a different table at ``out`` (only a table). While building, the
    table's lock is held; another process asking for it meanwhile waits (``notify`` says
    so) and then gets the finished table.
    """
    out = Path(out)
    key = request_key(structure, settings)
    if (nodes.digest() if nodes is not None else "") != settings.planned_nodes_sha256:
        raise ValueError("build_table: pass the NodePlan whose digest the settings hold (rcwa.table.planned)")
    check_materials(structure, settings)
    _refuse_before_lock(out, key, force)
    with entry_lock(out, notify=notify):
        return _build_locked(structure, settings, out, key, threads=threads, progress=progress, force=force,
                             executor=executor, nodes=nodes)


def _build_locked(structure: Structure, settings: TableSettings, out: Path, key: str, *, threads: int | None,
                  progress: bool, force: bool, executor, nodes: NodePlan | None = None) -> BuildReport:
    from tqdm import tqdm  # deferred: start-up time

    start = time.perf_counter()
    existed = out.exists()
    created = not existed or not any(out.iterdir())
    notes: list[str] = []
    store = _open_store(out, structure, settings, key, force, notes, nodes)
    done = read_progress(out)
    repaired = _drop_damaged_chunks(out, store, settings, done, notes)
    sym = symmetry_for(structure, settings)
    report = BuildReport(out, key, len(settings.wavelengths_nm), 0, len(done), 0.0, symmetry=sym.describe(),
                         notes=notes,
                         chunks_repaired=repaired)
    todo = [i for i in range(len(settings.wavelengths_nm)) if str(i) not in done]
    if not todo and store.attrs.get("complete"):
        report.cached = True
        report.seconds = time.perf_counter() - start
        report.bytes_on_disk = _size(out)
        return report
    try:
        _compute_chunks(structure, settings, out, store, todo, done, report, threads, executor, nodes,
                        tqdm(total=len(settings.wavelengths_nm), initial=len(done), unit="wavelength",
                             disable=not progress, desc=f"table {structure.name}"))
    except BaseException:
        if created and not done:  # nothing worth resuming: leave nothing behind (a folder the user made stays, empty)
            _remove_contents(out, keep_folder=existed)
        raise
    store.attrs.update({"complete": True, "chunk_seconds": {k: v["seconds"] for k, v in done.items()},
                        "truncation_error": {k: v["truncation"] for k, v in done.items() if "truncation" in v}})
    report.seconds = time.perf_counter() - start
    report.bytes_on_disk = _size(out)
    return report


def _remove_contents(out: Path, keep_folder: bool) -> None:
    if not keep_folder:
        shutil.rmtree(out, ignore_errors=True)
        return
    for child in out.iterdir():
        if child.is_dir():
            shutil.rmtree(child)
        else:
            child.unlink()


def _compute_chunks(structure: Structure, settings: TableSettings, out: Path, store, todo: list[int], done: dict,
                    report: BuildReport, threads: int | None, executor, nodes: NodePlan | None, bar) -> None:
    threads = threads or default_threads()
    masks = [None if nodes is None else nodes.mask[i] for i in range(len(settings.wavelengths_nm))]
    _record_missing_estimates(structure, settings, out, done, masks)
    if executor is None:
        results = ((i, timed(compute_chunk, structure, settings, settings.wavelengths_nm[i], threads, masks[i]),
                    estimate_truncation(structure, settings, i, masks[i])) for i in todo)
    else:
        futures = {i: (executor.submit(timed, compute_chunk, structure, settings, settings.wavelengths_nm[i], 1, masks[i]),
                       executor.submit(estimate_truncation, structure, settings, i, masks[i])) for i in todo}
        results = ((i, futures[i][0].result(), futures[i][1].result()) for i in todo)
    with bar:
        for i, ((arrays, (solves, refined, sectors)), seconds), estimate in results:
            _write_chunk(out, store, i, arrays, seconds, done, estimate)
            report.chunks_computed += 1
            report.eigen_solves += solves
            report.eigen_refined += refined
            report.sector_points += sectors
            bar.update(1)


def _drop_damaged_chunks(out: Path, store, settings: TableSettings, done: dict, notes: list[str]) -> list[int]:
    """Check every finished chunk against its checksum; forget the damaged ones (they are
    computed again) and say which.
    """
    arrays = {name: store[name] for name in store.attrs["arrays"]}  # opened once (_open_arrays checked them)
    try:
        whole = {name: array[...] for name, array in arrays.items()}  # one read when every chunk decodes
    except Exception:  # a truncated chunk file: read chunk by chunk below
        whole = None
    damaged = []
    for index in sorted(done, key=int):
        try:
            chunk = {name: (whole[name] if whole is not None else array)[int(index)] for name, array in arrays.items()}
            intact = chunk_hash(chunk) == done[index]["sha256"]
        except Exception:  # a truncated or unreadable chunk file
            intact = False
        if not intact:
            damaged.append(int(index))
            del done[index]
    if damaged:
        store.attrs["complete"] = False
        _atomic_write_json(out / "progress.json", done)
        listed = ", ".join(f"{i} ({settings.wavelengths_nm[i]:g} nm)" for i in damaged)
        notes.append(f"damaged chunk{'s' if len(damaged) > 1 else ''} {listed}: checksum mismatch, computed again")
    return damaged


def _foreign_entries(out: Path) -> list[str]:
    """What ``out`` holds that is not part of a table (hidden temporary files of atomic writes aside)."""
    return sorted(p.name for p in out.iterdir()
                  if p.name not in TABLE_FILES and not p.name.startswith(".progress.json."))


def _refuse_before_lock(out: Path, key: str, force: bool) -> None:
    """_refuse_unless_replaceable before waiting for the lock (so a wrong request fails at once), except on another
    process's build under way: its files are half-written while it holds the lock (a zarr.json without our
    metadata yet reads as a different table), so they are judged again under the lock (_open_store), once it is
    done. A build that finished between the two looks is judged on its final files."""
    try:
        _refuse_unless_replaceable(out, key, force)
    except UserInputError:
        if is_locked(out):
            return
        _refuse_unless_replaceable(out, key, force)


def _refuse_unless_replaceable(out: Path, key: str, force: bool) -> None:
    """Raise unless ``out`` is new, empty, the same request, or (with ``force``) another table."""
    if not out.exists():
        return
    if not out.is_dir():
        raise UserInputError("is a file, not a table folder", file=out, expected="a new path or an existing table")
    if not any(out.iterdir()):
        return
    foreign = _foreign_entries(out)
    if foreign:
        shown = ", ".join(foreign[:8]) + (f" and {len(foreign) - 8} more" if len(foreign) > 8 else "")
        raise UserInputError(f"the folder holds files that are not part of a table ({shown}); --force replaces only a "
                             "table, never other files", file=out, expected="a new path or an existing table")
    meta = read_meta(out)
    if meta is not None and meta.get("key") == key:
        return
    if not force:
        what = "a different table" if meta is not None else "a table whose zarr.json cannot be read"
        raise UserInputError(f"the output already holds {what}", file=out,
                             expected="a new path, the same request, or --force to replace that table")


def _open_store(out: Path, structure: Structure, settings: TableSettings, key: str, force: bool, notes: list[str],
                nodes: NodePlan | None = None):
    import zarr  # deferred: start-up time

    _refuse_unless_replaceable(out, key, force)  # again, under the lock
    if out.exists() and any(out.iterdir()):
        meta = read_meta(out)
        if meta is not None and meta.get("key") == key:
            group = _open_arrays(out, meta)
            if group is not None:
                return group
            notes.append("the table's array metadata was damaged: built again from scratch")
        else:
            notes.append("replaced the different table that was there (--force)")
        shutil.rmtree(out)
    group = zarr.open_group(str(out), mode="w")
    sym = symmetry_for(structure, settings)
    shape = (len(settings.wavelengths_nm), len(settings.theta_deg), len(settings.phi_deg), int(np.prod(settings.keep)),
             len(pol_names(settings.pol)))
    names = ["R"] + ([] if settings.reflection_only or not transmits(structure, settings) else ["T"])
    if settings.both_sides:
        names += [n + "_below" for n in names]
    for name in names:
        group.create_array(name, shape=shape, chunks=(1,) + shape[1:], dtype="float32", fill_value=np.nan)
    kept_m, kept_n = kept_indices(settings.keep)
    meta = {
        "format": "workbench-efficiency-table", "format_version": FORMAT_VERSION, "key": key,
        "structure_name": structure.name, "structure_source": structure.source, "structure_text": structure.text,
        "structure_sha256": structure.content_hash, "settings": settings.to_json(), "arrays": names,
        "axes": ["wavelength_nm", "theta_deg", "phi_deg", "order", "pol"], "pol_names": pol_names(settings.pol),
        "orders_m": [int(m) for m in kept_m], "orders_n": [int(n) for n in kept_n],
        "symmetry": {"mirror_x": sym.x, "mirror_y": sym.y, "mirror_diagonal": sym.diagonal,
                     "phi_range_deg": list(sym.azimuth_range()), "description": sym.describe(),
                     "note": sym.note},
        "grazing_theta_deg": GRAZING_THETA_DEG,
        "factorization": resolve_rule(settings.factorization, structure.dimension, structure.layers),
        "solver_version": workbench_version, "versions": versions("numpy", "scipy", "zarr"), "complete": False,
    }
    if nodes is not None:
        group.create_array(PLANNED_NODES, shape=nodes.mask.shape, dtype="bool", fill_value=False)[...] = nodes.mask
        meta["planned"] = {"nodes_sha256": nodes.digest(), "exact_nodes": int(nodes.mask.sum()),
                           "total_nodes": int(nodes.mask.size), "fill_orders": list(settings.fill_orders)}
    group.attrs.update(meta)
    _atomic_write_json(out / "progress.json", {})
    return group


def _open_arrays(out: Path, meta: dict):
    """The zarr group with every array the metadata names, or None when one cannot be opened."""
    import zarr  # deferred: start-up time

    try:
        group = zarr.open_group(str(out), mode="a")
        arrays = [group[name] for name in meta["arrays"]]
    except Exception:  # a deleted or damaged array zarr.json
        return None
    expected = len(meta["settings"]["wavelengths_nm"])
    intact = all(isinstance(a, zarr.Array) and a.shape[0] == expected for a in arrays)
    return group if intact else None


def _record_missing_estimates(structure: Structure, settings: TableSettings, out: Path, done: dict,
                              masks: list) -> None:
    """Finished chunks without a truncation-error record (written by a build from before
    records existed) get theirs, checkpointed one by one."""
    for index in sorted((k for k, v in done.items() if "truncation" not in v), key=int):
        done[index]["truncation"] = estimate_truncation(structure, settings, int(index), masks[int(index)])
        _atomic_write_json(out / "progress.json", done)


def _write_chunk(out: Path, store, index: int, arrays: dict[str, np.ndarray], seconds: float, done: dict,
                 estimate: dict | None = None) -> None:
    for name, values in arrays.items():
        store[name][index] = values
    done[str(index)] = {"sha256": chunk_hash(arrays), "seconds": round(seconds, 4)}
    if estimate is not None:
        done[str(index)]["truncation"] = estimate
    _atomic_write_json(out / "progress.json", done)


def chunk_hash(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 of one chunk's arrays (float32 bytes, by array name): what progress.json records."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        h.update(name.encode())
        h.update(np.ascontiguousarray(arrays[name], dtype=np.float32).tobytes())
    return h.hexdigest()


def _atomic_write_json(path: Path, data) -> None:
    atomic_write_text(path, json.dumps(data), sync=True)


def read_progress(out: Path) -> dict:
    """progress.json: the finished chunks' checksums and seconds ({} when missing or unreadable)."""
    try:
        found = json.loads((out / "progress.json").read_text())
    except (OSError, ValueError, RecursionError):  # ValueError: not JSON, or not text (UnicodeDecodeError)
        return {}
    return found if isinstance(found, dict) else {}


def read_meta(out: Path) -> dict | None:
    """The table's attributes from its zarr.json (None when missing or unreadable)."""
    try:
        attributes = json.loads((out / "zarr.json").read_text()).get("attributes", {})
    except (OSError, ValueError, AttributeError, RecursionError):  # ValueError: not JSON, or not text
        return None
    return attributes if isinstance(attributes, dict) else None


def _size(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())

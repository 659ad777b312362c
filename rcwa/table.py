"""Efficiency tables: the renderer's input, built by sweeps, stored chunked on disk.

A table holds, for the kept orders of a structure, the diffraction efficiencies over a
grid of wavelength x polar angle x azimuth of the incident light (rcwa conventions:
(theta, phi) of the incident tangential wave vector), for reflection and, where the
substrate lets light through, transmission; optionally also for light from below (the
z-inverted structure, Lange et al. 2021, Sec. 2.2, for see-through elements).

Storage: a zarr v3 directory store, one chunk per wavelength, float32. A chunk counts as
written only once its SHA-256 is in ``progress.json`` (replaced atomically after each
chunk), so a killed build resumes from its finished chunks and a truncated or altered
table is detected (checksums) instead of read as data. The request's content hash
(structure text, grid, settings, solver version) names what a table holds; asking again
for a finished table returns it at once, after checking every chunk against its checksum:
damaged chunks are computed again.

Safety: the request is validated (settings, the materials' data over the wavelengths)
before anything is written; a build that fails before finishing a chunk removes what it
created; ``force`` replaces only a table (a folder holding nothing but a table's files),
never anything else. A build holds the table's file lock (workbench.core.cache), so a
second process asking for the same table waits and then reuses it.

Azimuths: mirror symmetries of the cell (rcwa.symmetry) shrink the azimuth range that is
computed (0-90 deg with the x and y mirrors; 0-45 deg when a square cell with a square
truncation also has the diagonal mirror x <-> y); ``Table.fold_azimuth`` maps any azimuth
into it (with the order flips and the swap, rcwa.symmetry.fold_azimuths). The stored
azimuths reach the range's end: where the step does not divide the range, the last node
lies one step past it, so bilinear interpolation up to the end never clamps. Metadata of
tables written before the diagonal mirror existed lack ``mirror_diagonal``: read as False.
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from rcwa import symmetry
from rcwa.structure import Layer, Structure
from rcwa.sweep import default_threads, sweep_directions
from workbench.core.cache import entry_lock, is_locked
from workbench.core.errors import UserInputError
from workbench.core.files import atomic_write_text
from workbench.core.timing import timed
from workbench.core.version import __version__ as workbench_version
from workbench.core.version import versions

FORMAT_VERSION = 1
GRAZING_THETA_DEG = 89.999  # theta = 90 (no incident power) is solved at this limit
POLARIZATIONS = ("unpolarized", "s", "p", "all")
ARRAY_NAMES = ("R", "T", "R_below", "T_below")
PLANNED_NODES = "planned_nodes"  # a planned table's mask of exactly solved nodes (wavelength, theta, phi)
TABLE_FILES = ("zarr.json", "progress.json", PLANNED_NODES) + ARRAY_NAMES  # everything a table folder holds


@dataclass(frozen=True)
class TableSettings:
    wavelengths_nm: tuple[float, ...]
    theta_deg: tuple[float, ...]
    phi_deg: tuple[float, ...]
    orders: tuple[int, ...]
    keep: tuple[int, ...]
    pol: str = "unpolarized"
    reflection_only: bool = False
    both_sides: bool = False
    factorization: str = "auto"
    use_symmetry: bool = True
    planned_nodes_sha256: str = ""   # a planned table (NodePlan): the digest of its mask; "" for a whole table
    fill_orders: tuple[int, ...] = ()  # a planned table: the retained orders of the nodes outside the mask

    def to_json(self) -> dict:
        data = asdict(self)
        if not self.planned_nodes_sha256:  # a whole table's request (and key) as before planning existed
            del data["planned_nodes_sha256"], data["fill_orders"]
        return data


@dataclass(frozen=True)
class NodePlan:
    """The grid nodes a render reads (renderer.planner), solved with the table's orders; the
    others are solved with only ``fill_orders`` retained (at least the kept orders).

    Why the others are not left empty: a path that meets the element after a diffuse
    bounce (the element's light thrown onto a wall, seen by the camera) reads directions no
    camera ray reads directly. Those paths are dim and already blurred by the bounce, so a
    less converged solve serves them; its error is measured and reported by the planner
    (renderer.planner) and the render's equality within Monte Carlo noise is tested.
    """

    mask: np.ndarray               # (wavelengths, theta, phi) bool: solved with the table's orders
    fill_orders: tuple[int, ...]

    def digest(self) -> str:
        mask = np.ascontiguousarray(self.mask, dtype=bool)
        h = hashlib.sha256(json.dumps({"shape": list(mask.shape), "fill_orders": list(self.fill_orders)}).encode())
        h.update(np.packbits(mask).tobytes())
        return h.hexdigest()


def planned(settings: TableSettings, nodes: NodePlan) -> TableSettings:
    """``settings`` for a table whose nodes outside ``nodes.mask`` use ``nodes.fill_orders``."""
    shape = (len(settings.wavelengths_nm), len(settings.theta_deg), len(settings.phi_deg))
    if nodes.mask.shape != shape:
        raise UserInputError("the planned nodes do not match the table's grid", field="nodes",
                             expected=f"a mask of shape {shape} (wavelength, theta, phi)", got=list(nodes.mask.shape))
    fill = _counts(tuple(nodes.fill_orders), len(settings.orders), "fill_orders")
    if any(f < k or f > o for f, k, o in zip(fill, settings.keep, settings.orders, strict=True)):
        raise UserInputError("the fill's orders must lie between the kept and the retained orders", field="fill_orders",
                             expected=f"{list(settings.keep)} <= N <= {list(settings.orders)}", got=list(fill))
    return replace(settings, planned_nodes_sha256=nodes.digest(), fill_orders=fill)


PRESETS: dict[str, dict] = {
    # the paper's table: 2 deg steps over 0-90 deg, 31 wavelengths, 61 orders, 11 kept
    "paper": {"wavelengths": (400.0, 700.0, 31), "theta_step": 2.0, "phi_step": 2.0,
              "orders": {1: 61, 2: 11}, "keep": {1: 11, 2: 5}},
    "draft": {"wavelengths": (400.0, 700.0, 11), "theta_step": 5.0, "phi_step": 10.0,
              "orders": {1: 31, 2: 7}, "keep": {1: 11, 2: 5}},
    "fine": {"wavelengths": (380.0, 780.0, 81), "theta_step": 1.0, "phi_step": 1.0,
             "orders": {1: 81, 2: 15}, "keep": {1: 15, 2: 7}},
}


def parse_wavelengths(text: str) -> tuple[float, ...]:
    """``START:STOP:COUNT`` (inclusive, like numpy.linspace) or a comma-separated list, in nm."""
    try:
        if ":" in text:
            start, stop, count = text.split(":")
            start_f, stop_f, count_i = float(start), float(stop), int(count)
            if count_i < 1 or stop_f < start_f or (count_i > 1 and stop_f == start_f):
                raise ValueError
            return tuple(float(v) for v in np.linspace(start_f, stop_f, count_i))
        values = tuple(float(v) for v in text.split(",") if v.strip())
        if not values:
            raise ValueError
        return values
    except ValueError:
        raise UserInputError(
            "not a wavelength range", field="--wavelengths",
            expected="START:STOP:COUNT with STOP >= START and COUNT >= 1 (e.g. 400:700:31), or NM,NM,...", got=text,
        ) from None


def angle_grid(step: float, start: float, stop: float, name: str, *, cover: bool = False) -> tuple[float, ...]:
    """``start``, ``start + step``, ... up to ``stop`` (inclusive, to 1e-9 steps); with
    ``cover``, where the step does not divide the range, one node past ``stop`` (an
    azimuth grid must reach its range's end, which the fold maps onto itself)."""
    if not (isinstance(step, (int, float)) and math.isfinite(step) and step > 0):
        raise UserInputError("the angular step must be positive", field=name, expected="a step > 0 degrees", got=step)
    steps = (stop - start) / step
    count = int(math.ceil(steps - 1e-9) if cover else math.floor(steps + 1e-9)) + 1
    values = start + step * np.arange(count)
    return tuple(float(v) for v in values)


def settings_for(structure: Structure, preset: str = "paper", *, theta_step: float | None = None, phi_step: float | None = None,
                 wavelengths: str | None = None, orders: int | tuple[int, ...] | None = None,
                 keep: int | tuple[int, ...] | None = None, pol: str = "unpolarized", reflection_only: bool = False,
                 both_sides: bool = False, factorization: str = "auto", use_symmetry: bool = True,
                 theta_range: tuple[float, float] | None = None, phi_range: tuple[float, float] | None = None) -> TableSettings:
    """Settings from a preset and explicit overrides, validated (errors name the option).

    ``theta_range`` / ``phi_range`` (degrees, inclusive) restrict the grid to the part of
    the domain a scene can reach; azimuths are those of the stored (symmetry-folded)
    range, which a range must lie inside.
    """
    if preset not in PRESETS:
        raise UserInputError("unknown preset", field="--preset", expected=f"one of {sorted(PRESETS)}", got=preset)
    if pol not in POLARIZATIONS:
        raise UserInputError("unknown polarization", field="--pol", expected=f"one of {POLARIZATIONS}", got=pol)
    p = PRESETS[preset]
    dim = structure.dimension
    start, stop, count = p["wavelengths"]
    wl = parse_wavelengths(wavelengths) if wavelengths else tuple(float(v) for v in np.linspace(start, stop, count))
    counts = _counts(orders if orders is not None else p["orders"][dim], dim, "--orders")
    kept = _counts(keep if keep is not None else min(p["keep"][dim], counts[0]), dim, "--keep-orders")
    if any(k > c for k, c in zip(kept, counts, strict=True)):
        raise UserInputError("cannot keep more orders than are retained", field="--keep-orders",
                             expected=f"at most {list(counts)}", got=list(kept))
    sym = table_symmetry(structure, counts, kept, use_symmetry)
    lo, hi = sym.azimuth_range()
    t_lo, t_hi = _range(theta_range, (0.0, 90.0), "--theta-range")
    p_lo, p_hi = _range(phi_range, (lo, hi), "--phi-range")
    theta = angle_grid(theta_step if theta_step is not None else p["theta_step"], t_lo, t_hi, "--theta-step")
    full_turn = p_hi - p_lo == 360  # 360 deg is 0 deg again
    phi = angle_grid(phi_step if phi_step is not None else p["phi_step"], p_lo, p_hi - (1e-9 if full_turn else 0.0),
                     "--phi-step", cover=not full_turn)
    return TableSettings(wl, theta, phi, counts, kept, pol, reflection_only, both_sides, factorization, use_symmetry)


def table_symmetry(structure: Structure, orders: tuple[int, ...], keep: tuple[int, ...],
                   use_symmetry: bool = True) -> symmetry.MirrorSymmetry:
    """The mirrors a table of these retained / kept orders uses (rcwa.symmetry.detect;
    none without ``use_symmetry``). Every writer and planner of a table asks here."""
    if not use_symmetry:
        return symmetry.MirrorSymmetry(False, False)
    return symmetry.detect(structure, orders, keep)


def _range(value: tuple[float, float] | None, bounds: tuple[float, float], name: str) -> tuple[float, float]:
    if value is None:
        return bounds
    lo, hi = (float(v) for v in value)
    if not (bounds[0] <= lo <= hi <= bounds[1]):
        raise UserInputError("the range must be ordered and inside the stored domain", field=name,
                             expected=f"{bounds[0]:g} <= LO <= HI <= {bounds[1]:g} degrees", got=[lo, hi])
    return lo, hi


def _counts(value, dim: int, name: str) -> tuple[int, ...]:
    values = (value,) * dim if isinstance(value, (int, np.integer)) else tuple(value)
    odd = all(not isinstance(v, bool) and isinstance(v, (int, np.integer)) and v >= 1 and v % 2 == 1 for v in values)
    if len(values) != dim or not odd:
        raise UserInputError("order counts must be positive odd integers, one per periodic direction", field=name,
                             expected="N" if dim == 1 else "NX,NY", got=value)
    return tuple(int(v) for v in values)


def request_key(structure: Structure, settings: TableSettings) -> str:
    """Content hash of what a table holds (structure text, settings, solver version)."""
    payload = json.dumps({"structure": structure.text, "settings": settings.to_json(), "format": FORMAT_VERSION,
                          "version": workbench_version}, sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()


def flipped(structure: Structure) -> Structure:
    """The z-inverted structure: light from below sees the substrate as its superstrate."""
    layers = tuple(Layer(layer.thickness, layer.material, layer.shapes, layer.name) for layer in reversed(structure.layers))
    return replace(structure, superstrate=structure.substrate, substrate=structure.superstrate, layers=layers)


# ---------------------------------------------------------------- building


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


def compute_chunk(structure: Structure, settings: TableSettings, wavelength_nm: float,
                  threads: int, mask: np.ndarray | None = None) -> tuple[dict[str, np.ndarray], tuple[int, int, int]]:
    """All arrays of one wavelength: R (and T; and from below), (theta, phi, order, pol);
    and the sweeps' (eigen-solves, refined eigen-solves, directions solved in mirror
    sectors: a 2D cell's in its mirror planes, rcwa.sweep).

    ``mask`` (theta, phi) of a planned table: the nodes solved with the table's orders;
    the rest with ``settings.fill_orders``.
    """
    theta = np.array([min(t, GRAZING_THETA_DEG) for t in settings.theta_deg])
    th, ph = np.meshgrid(theta, np.array(settings.phi_deg), indexing="ij")
    exact = np.ones(th.size, bool) if mask is None else np.asarray(mask, bool).ravel()
    groups = [(exact, settings.orders), (~exact, settings.fill_orders or settings.orders)]
    out, solves, refined, sectors = {}, 0, 0, 0
    sides = [("", structure)] + ([("_below", flipped(structure))] if settings.both_sides else [])
    for suffix, s in sides:
        values: dict[str, np.ndarray] = {}
        for nodes, orders in groups:
            if not nodes.any():
                continue
            sw = sweep_directions(s, wavelength_nm, th.ravel()[nodes], ph.ravel()[nodes], orders, keep=settings.keep,
                                  factorization=settings.factorization, threads=threads)
            solves, refined, sectors = solves + sw.eigen_solves, refined + sw.eigen_refined, sectors + sw.sector_points
            for name, part in (("R", sw.R), ("T", sw.T)):
                values.setdefault(name, np.empty((th.size,) + part.shape[1:]))[nodes] = part
        for name, whole in values.items():
            if name == "T" and (settings.reflection_only or not transmits(s, settings)):
                continue
            out[name + suffix] = _select_pol(whole, settings.pol).reshape(th.shape + (whole.shape[1], -1)).astype(np.float32)
    return out, (solves, refined, sectors)


def _select_pol(values: np.ndarray, pol: str) -> np.ndarray:
    unpolarized = values.mean(axis=-1, keepdims=True)
    return {"s": values[..., :1], "p": values[..., 1:], "unpolarized": unpolarized,
            "all": np.concatenate([values, unpolarized], axis=-1)}[pol]


def pol_names(pol: str) -> list[str]:
    return ["s", "p", "unpolarized"] if pol == "all" else [pol]


def check_materials(structure: Structure, settings: TableSettings) -> None:
    """Every medium of ``structure`` has data at every wavelength of ``settings`` (checked
    before a table is written, so a bad range leaves nothing behind).
    """
    wavelengths = np.asarray(settings.wavelengths_nm)
    media = [structure.superstrate, structure.substrate]
    for layer in structure.layers:
        media += [layer.material] + [shape.material for shape in layer.shapes]
    for material in media:
        try:
            material.epsilon(wavelengths)
        except UserInputError as exc:
            raise UserInputError(f"{exc.reason}; the table's wavelengths must lie inside every material's data",
                                 file=structure.source, field=structure.field_of(material),
                                 expected="--wavelengths inside that range") from None


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
    from tqdm import tqdm

    start = time.perf_counter()
    existed = out.exists()
    created = not existed or not any(out.iterdir())
    notes: list[str] = []
    store = _open_store(out, structure, settings, key, force, notes, nodes)
    done = _read_progress(out)
    repaired = _drop_damaged_chunks(out, store, settings, done, notes)
    sym = table_symmetry(structure, settings.orders, settings.keep, settings.use_symmetry)
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
    store.attrs.update({"complete": True, "chunk_seconds": {k: v["seconds"] for k, v in done.items()}})
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
    if executor is None:
        results = ((i, timed(compute_chunk, structure, settings, settings.wavelengths_nm[i], threads, masks[i]))
                   for i in todo)
    else:
        futures = {i: executor.submit(timed, compute_chunk, structure, settings, settings.wavelengths_nm[i], 1, masks[i])
                   for i in todo}
        results = ((i, futures[i].result()) for i in todo)
    with bar:
        for i, ((arrays, (solves, refined, sectors)), seconds) in results:
            _write_chunk(out, store, i, arrays, seconds, done)
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
            intact = _chunk_hash(chunk) == done[index]["sha256"]
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
    meta = _read_meta(out)
    if meta is not None and meta.get("key") == key:
        return
    if not force:
        what = "a different table" if meta is not None else "a table whose zarr.json cannot be read"
        raise UserInputError(f"the output already holds {what}", file=out,
                             expected="a new path, the same request, or --force to replace that table")


def _open_store(out: Path, structure: Structure, settings: TableSettings, key: str, force: bool, notes: list[str],
                nodes: NodePlan | None = None):
    import zarr

    _refuse_unless_replaceable(out, key, force)  # again, under the lock
    if out.exists() and any(out.iterdir()):
        meta = _read_meta(out)
        if meta is not None and meta.get("key") == key:
            group = _open_arrays(out, meta)
            if group is not None:
                return group
            notes.append("the table's array metadata was damaged: built again from scratch")
        else:
            notes.append("replaced the different table that was there (--force)")
        shutil.rmtree(out)
    group = zarr.open_group(str(out), mode="w")
    sym = table_symmetry(structure, settings.orders, settings.keep, settings.use_symmetry)
    shape = (len(settings.wavelengths_nm), len(settings.theta_deg), len(settings.phi_deg), int(np.prod(settings.keep)),
             len(pol_names(settings.pol)))
    names = ["R"] + ([] if settings.reflection_only or not transmits(structure, settings) else ["T"])
    if settings.both_sides:
        names += [n + "_below" for n in names]
    for name in names:
        group.create_array(name, shape=shape, chunks=(1,) + shape[1:], dtype="float32", fill_value=np.nan)
    from rcwa.factorization import resolve_rule

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
    import zarr

    try:
        group = zarr.open_group(str(out), mode="a")
        arrays = [group[name] for name in meta["arrays"]]
    except Exception:  # a deleted or damaged array zarr.json
        return None
    expected = len(meta["settings"]["wavelengths_nm"])
    intact = all(isinstance(a, zarr.Array) and a.shape[0] == expected for a in arrays)
    return group if intact else None


def transmits(structure: Structure, settings: TableSettings) -> bool:
    """Whether any light reaches infinity below (a lossless substrate at some wavelength)."""
    eps = np.asarray(structure.substrate.epsilon(np.asarray(settings.wavelengths_nm)))
    return bool(np.any((eps.imag == 0) & (eps.real > 0)))


def kept_indices(keep: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Kept orders in the order the sweep returns them (m-major, as the solver's harmonics)."""
    ms = np.arange(keep[0]) - keep[0] // 2
    if len(keep) == 1:
        return ms, np.zeros_like(ms)
    ns = np.arange(keep[1]) - keep[1] // 2
    M, N = np.meshgrid(ms, ns, indexing="ij")
    return M.ravel(), N.ravel()


def _write_chunk(out: Path, store, index: int, arrays: dict[str, np.ndarray], seconds: float, done: dict) -> None:
    for name, values in arrays.items():
        store[name][index] = values
    done[str(index)] = {"sha256": _chunk_hash(arrays), "seconds": round(seconds, 4)}
    _atomic_write_json(out / "progress.json", done)


def _chunk_hash(arrays: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        h.update(name.encode())
        h.update(np.ascontiguousarray(arrays[name], dtype=np.float32).tobytes())
    return h.hexdigest()


def _atomic_write_json(path: Path, data) -> None:
    atomic_write_text(path, json.dumps(data), sync=True)


def _read_progress(out: Path) -> dict:
    try:
        return json.loads((out / "progress.json").read_text())
    except (OSError, json.JSONDecodeError):
        return {}


def _read_meta(out: Path) -> dict | None:
    try:
        return json.loads((out / "zarr.json").read_text()).get("attributes", {})
    except (OSError, json.JSONDecodeError, AttributeError):
        return None


def read_table_metadata(path: str | Path) -> dict:
    """A table's metadata (grid, settings, symmetry, orders) without reading its data.

    Raises UserInputError naming the path when it is not a table of ours.
    """
    path = Path(path)
    meta = _read_meta(path) if path.is_dir() else None
    if meta is None or meta.get("format") != "workbench-efficiency-table":
        raise UserInputError("not an efficiency table (no readable zarr.json with our format)", file=path,
                             expected="a folder written by `workbench rcwa table`")
    return meta


def _size(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


# ---------------------------------------------------------------- reading


@dataclass
class Table:
    """A finished, verified table. ``arrays[name]``: (wavelength, theta, phi, order, pol)."""

    path: Path
    meta: dict
    arrays: dict[str, np.ndarray]

    @property
    def wavelengths_nm(self) -> np.ndarray:
        return np.asarray(self.meta["settings"]["wavelengths_nm"])

    @property
    def theta_deg(self) -> np.ndarray:
        return np.asarray(self.meta["settings"]["theta_deg"])

    @property
    def phi_deg(self) -> np.ndarray:
        return np.asarray(self.meta["settings"]["phi_deg"])

    @property
    def orders(self) -> list[tuple[int, int]]:
        return list(zip(self.meta["orders_m"], self.meta["orders_n"], strict=True))

    @property
    def mirrors(self) -> tuple[bool, bool, bool]:
        """(x, y, diagonal) mirrors the table's azimuths are folded by; tables written
        before the diagonal existed have no ``mirror_diagonal``: False."""
        sym = self.meta["symmetry"]
        return bool(sym["mirror_x"]), bool(sym["mirror_y"]), bool(sym.get("mirror_diagonal", False))

    def fold_azimuth(self, phi_deg: float) -> tuple[float, bool, bool, bool]:
        """Map an azimuth into the stored range: (phi, flip m, flip n, swap m and n); order
        (m, n) is stored as rcwa.symmetry.stored_order(m, n, flip m, flip n, swap)
        (rcwa.symmetry.fold_azimuths)."""
        phi, flip_m, flip_n, swap = symmetry.fold_azimuths(float(phi_deg), *self.mirrors)
        return float(phi), bool(flip_m), bool(flip_n), bool(swap)

    def stored_index(self, m: int, n: int, flip_m: bool, flip_n: bool, swap: bool) -> int:
        """Index (into the order axis) of the stored order that holds order (m, n) at a
        folded azimuth (fold_azimuth's flips and swap)."""
        sm, sn = symmetry.stored_order(m, n, flip_m, flip_n, swap)
        return self.orders.index((int(sm), int(sn)))


def open_table(path: str | Path) -> Table:
    """Open a finished table, verifying every chunk's checksum; clear errors otherwise."""
    import zarr

    path = Path(path)
    meta = _read_meta(path)
    if meta is None or meta.get("format") != "workbench-efficiency-table":
        raise UserInputError("not an efficiency table (no readable zarr.json with our format)", file=path)
    repair = _repair_advice(path, meta)
    if not meta.get("complete"):
        raise UserInputError(f"the table is unfinished; {repair} to resume it", file=path)
    done = _read_progress(path)
    group = zarr.open_group(str(path), mode="r")
    arrays: dict[str, np.ndarray] = {}
    count = len(meta["settings"]["wavelengths_nm"])
    for name in meta["arrays"]:
        try:
            arrays[name] = np.stack([_read_chunk(group, name, i) for i in range(count)])
        except _ChunkUnreadable as exc:
            raise UserInputError(f"array {name}, {_chunk_words(meta, exc.index)} cannot be read ({exc.reason}); "
                                 f"{repair}: damaged chunks are computed again", file=path) from None
    for i in range(count):
        record = done.get(str(i))
        if record is None or _chunk_hash({name: arrays[name][i] for name in arrays}) != record["sha256"]:
            raise UserInputError(f"{_chunk_words(meta, i)} is damaged or missing (its checksum does not match); "
                                 f"{repair}: damaged chunks are computed again", file=path)
    return Table(path, meta, arrays)


class _ChunkUnreadable(Exception):
    def __init__(self, index: int, reason: str) -> None:
        super().__init__(reason)
        self.index, self.reason = index, reason


def _read_chunk(group, name: str, index: int) -> np.ndarray:
    try:
        return group[name][index]
    except Exception as exc:  # a truncated chunk file, a deleted array
        raise _ChunkUnreadable(index, f"{type(exc).__name__}: {exc}") from None


def _chunk_words(meta: dict, index: int) -> str:
    return f"chunk {index} (wavelength {meta['settings']['wavelengths_nm'][index]:g} nm)"


def _repair_advice(path: Path, meta: dict) -> str:
    """The command that rebuilds a table: the one that made it (the render of a scene, for a cached one)."""
    source = str(meta.get("structure_source", "STRUCTURE"))
    structure = meta.get("structure_name", source) if source.startswith("<built-in") else source
    return (f"run `workbench rcwa table {structure} --out {path}` with the options that built it (or the render that "
            "uses it) again")


_transmits = transmits  # until renderer.planner imports the public names (issue 24)
_kept_indices = kept_indices

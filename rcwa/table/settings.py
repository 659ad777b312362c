"""What a table holds: its settings (the grid of wavelength x polar angle x azimuth, the
retained and kept orders, the polarization, the sides), the presets, and the request's
content key (structure text, settings, solver version) that names a table.

Settings are validated where they enter (``settings_for``: errors name the command line's
option). The azimuths are those of the range the cell's mirrors leave to compute
(``table_symmetry``, rcwa.symmetry); the order axis lists the kept orders m-major
(``kept_indices``), as the solver's harmonics.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass, replace

import numpy as np

from rcwa import symmetry
from rcwa.structure import Structure
from workbench.core.errors import UserInputError
from workbench.core.version import __version__ as workbench_version

FORMAT_VERSION = 1
GRAZING_THETA_DEG = 89.999  # theta = 90 (no incident power) is solved at this limit
POLARIZATIONS = ("unpolarized", "s", "p", "all")
# Sizes refused before anything is allocated (issue 46, cause 1): a grid's node counts are known
# from the request's numbers alone, so a 0.00001 deg step or 1e8 wavelengths is refused at once.
MAX_WAVELENGTHS = 10_000  # 0.03 nm apart over the visible: far finer than any camera or light resolves
MAX_ANGLE_NODES = 90_001  # a 0.001 deg step over 0-90 deg
TABLE_MEMORY_FRACTION = 0.5  # a table is read whole by a render: at most half of this machine's memory


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
    """The grid nodes a render reads (renderer.trace.planner), solved with the table's orders; the
    others are solved with only ``fill_orders`` retained (at least the kept orders).

    Why the others are not left empty: a path that meets the element after a diffuse
    bounce (the element's light thrown onto a wall, seen by the camera) reads directions no
    camera ray reads directly. Those paths are dim and already blurred by the bounce, so a
    less converged solve serves them; its error is measured and reported by the planner
    (renderer.trace.planner) and the render's equality within Monte Carlo noise is tested.
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
    if text.count(",") >= MAX_WAVELENGTHS:  # before the list is parsed
        _check_count(text.count(",") + 1, MAX_WAVELENGTHS, "--wavelengths", "wavelengths")
    try:
        if ":" in text:
            start, stop, count = text.split(":")
            start_f, stop_f, count_i = float(start), float(stop), int(count)
            if count_i < 1 or stop_f < start_f or (count_i > 1 and stop_f == start_f) or not math.isfinite(stop_f):
                raise ValueError
        else:
            values = tuple(float(v) for v in text.split(",") if v.strip())
            if not values or not all(math.isfinite(v) and v > 0 for v in values):
                raise ValueError
            return values
    except ValueError:
        raise UserInputError(
            "not a wavelength range", field="--wavelengths",
            expected="START:STOP:COUNT with STOP >= START and COUNT >= 1 (e.g. 400:700:31), or NM,NM,...", got=text,
        ) from None
    _check_count(count_i, MAX_WAVELENGTHS, "--wavelengths", "wavelengths")
    return tuple(float(v) for v in np.linspace(start_f, stop_f, count_i))


def angle_grid(step: float, start: float, stop: float, name: str, *, cover: bool = False) -> tuple[float, ...]:
    """``start``, ``start + step``, ... up to ``stop`` (inclusive, to 1e-9 steps); with
    ``cover``, where the step does not divide the range, one node past ``stop`` (an
    azimuth grid must reach its range's end, which the fold maps onto itself)."""
    if not (isinstance(step, (int, float)) and math.isfinite(step) and step > 0):
        raise UserInputError("the angular step must be positive", field=name, expected="a step > 0 degrees", got=step)
    steps = (stop - start) / step
    _check_count(steps, MAX_ANGLE_NODES, name, "angles")
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
    settings = TableSettings(wl, theta, phi, counts, kept, pol, reflection_only, both_sides, factorization, use_symmetry)
    check_table_memory(settings)
    return settings


def _check_count(count: float, limit: int, field: str, what: str) -> None:
    if count > limit:
        raise UserInputError(f"asks for {count:.3g} {what}, more than the {limit} a table may hold along one axis",
                             field=field, expected=f"at most {limit} {what}")


def table_bytes(settings: TableSettings) -> int:
    """The bytes of a table's arrays held in memory at once (a render reads it whole): float32 per
    (wavelength, theta, phi, kept order, polarization), for R, T and, with both sides, their ``_below``."""
    nodes = len(settings.wavelengths_nm) * len(settings.theta_deg) * len(settings.phi_deg)
    arrays = (1 if settings.reflection_only else 2) * (2 if settings.both_sides else 1)
    return nodes * math.prod(settings.keep) * len(pol_names(settings.pol)) * arrays * 4


def check_table_memory(settings: TableSettings, total_bytes: int | None = None) -> None:
    """Refuse a table that would not fit in memory, with the estimate in the message (as the solver's
    ``--orders`` check does): more than TABLE_MEMORY_FRACTION of this machine's memory."""
    if total_bytes is None:
        try:
            total_bytes = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            return
    need = table_bytes(settings)
    if need > TABLE_MEMORY_FRACTION * total_bytes:
        grid = f"{len(settings.wavelengths_nm)} x {len(settings.theta_deg)} x {len(settings.phi_deg)}"
        raise UserInputError(f"the table ({grid} nodes, {math.prod(settings.keep)} kept orders) needs about "
                             f"{need / 2**30:.1f} GiB, more than half of this machine's {total_bytes / 2**30:.0f} GiB",
                             field="--theta-step/--phi-step/--wavelengths/--keep-orders",
                             expected="coarser steps, fewer wavelengths or fewer kept orders")


def table_symmetry(structure: Structure, orders: tuple[int, ...], keep: tuple[int, ...],
                   use_symmetry: bool = True) -> symmetry.MirrorSymmetry:
    """The mirrors a table of these retained / kept orders uses (rcwa.symmetry.detect;
    none without ``use_symmetry``). Every writer and planner of a table asks here."""
    if not use_symmetry:
        return symmetry.MirrorSymmetry(False, False)
    return symmetry.detect(structure, orders, keep)


def symmetry_for(structure: Structure, settings: TableSettings) -> symmetry.MirrorSymmetry:
    """table_symmetry of a table with these settings."""
    return table_symmetry(structure, settings.orders, settings.keep, settings.use_symmetry)


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


def pol_names(pol: str) -> list[str]:
    return ["s", "p", "unpolarized"] if pol == "all" else [pol]


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

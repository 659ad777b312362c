"""Raw RCWA solves of a convergence study, cached in one JSON file so that reruns are cheap.

A high-truncation 2D solve costs minutes (gold2d at 51 x 51 harmonics: about 10^2 s on
one core), and a convergence table needs dozens of them. Each solve's efficiencies (every
propagating order's, per polarization), its seconds and its peak memory are written to
the cache file atomically right after the solve (a checkpoint: an interrupted run loses
at most the solve in flight). Entries are keyed by the structure's content hash, the
direction, the wavelength, the truncation and the factorization rule, so a changed
structure never reuses a stale entry; the solver's version is recorded beside each entry.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import rcwa
from rcwa.asr import DEFAULT_ETA as ASR_ETA
from rcwa.asr import solve_asr
from rcwa.solver import prepare
from rcwa.structure import Structure
from rcwa.symmetry import has_diagonal_mirror
from workbench.core.cache import cache_root
from workbench.core.files import atomic_write_text, path_safe_name
from workbench.core.version import __version__

CACHE_FORMAT = 1
# The factorization rules' names (rcwa.factorization) and these two: Li's rule and the normal-vector
# rule in the stretched coordinates of adaptive spatial resolution (rcwa.asr, at its DEFAULT_ETA),
# each mapped to the in-plane rule solve_asr takes.
ASR_RULE = "asr"
ASR_NV_RULE = "asr_nv"
ASR_RULES = {ASR_RULE: "li", ASR_NV_RULE: "nv"}
CACHE_ENVIRONMENT = "RCWA_CONVERGENCE_CACHE"  # a folder: where convergence studies keep their raw solves
_CLEAR_REFS = Path("/proc/self/clear_refs")
_STATUS = Path("/proc/self/status")


@dataclass(frozen=True)
class Direction:
    """One incidence: wavelength (nm) and angles (degrees, workbench.core.conventions)."""

    wavelength_nm: float
    theta_deg: float
    phi_deg: float = 0.0

    def key(self) -> str:
        return f"{self.wavelength_nm:.10g}nm/{self.theta_deg:.10g}/{self.phi_deg:.10g}"


@dataclass(frozen=True)
class RawSolve:
    """One unpolarized solve's numbers: per polarization (index 0 = s, 1 = p) the totals and
    every propagating order's efficiencies ``orders[(m, n)] = (R_s, R_p, T_s, T_p)``."""

    R_total: tuple[float, float]
    T_total: tuple[float, float]
    orders: dict[tuple[int, int], tuple[float, float, float, float]]
    seconds: float
    peak_rss_bytes: int | None
    # The solve alone once the layer's direction-free matrices are built and cached (as in a table, where one
    # layer's normal-vector field serves every node): measured only where asked (solve_raw(warm=True)).
    warm_seconds: float | None = None

    def efficiency(self, side: str, m: int, n: int, pol: int) -> float:
        """R (``side="R"``) or T of order (m, n) for polarization ``pol`` (0 = s, 1 = p);
        0 for an order that does not propagate on that side."""
        values = self.orders.get((m, n))
        if values is None:
            return 0.0
        return values[pol if side == "R" else 2 + pol]

    def to_json(self) -> dict[str, Any]:
        return {"R_total": list(self.R_total), "T_total": list(self.T_total), "seconds": self.seconds,
                "peak_rss_bytes": self.peak_rss_bytes, "warm_seconds": self.warm_seconds,
                "orders": [[m, n, *v] for (m, n), v in sorted(self.orders.items())]}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> RawSolve:
        orders = {(int(o[0]), int(o[1])): (float(o[2]), float(o[3]), float(o[4]), float(o[5])) for o in data["orders"]}
        r, t = data["R_total"], data["T_total"]
        warm = data.get("warm_seconds")
        return cls((float(r[0]), float(r[1])), (float(t[0]), float(t[1])), orders, float(data["seconds"]),
                   data.get("peak_rss_bytes"), None if warm is None else float(warm))


def default_cache_path(structure_name: str) -> Path:
    """``NAME_raw.json`` in ``$RCWA_CONVERGENCE_CACHE`` if set, else in ``convergence/`` of the workbench cache."""
    chosen = os.environ.get(CACHE_ENVIRONMENT)
    folder = Path(chosen).expanduser() if chosen else cache_root() / "convergence"
    return folder / f"{path_safe_name(structure_name)}_raw.json"


def _reset_peak_rss() -> bool:
    """Reset the process's peak resident set (Linux: ``5`` into /proc/self/clear_refs)."""
    try:
        _CLEAR_REFS.write_text("5")
        return True
    except OSError:
        return False


def _peak_rss_bytes() -> int | None:
    try:
        for line in _STATUS.read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def solve_raw(structure: Structure, direction: Direction, orders: int, rule: str, *, warm: bool = False) -> RawSolve:
    """One solve at ``orders`` x ``orders`` harmonics for s and p, timed, with its peak memory
    (the process's peak resident set during the solve; None where it cannot be read).
    ``warm``: build the layer's matrices first (rcwa.solver.prepare, which caches the
    normal-vector field) and time the solve after it as ``warm_seconds`` too; ``seconds``
    is then the two together (a one-off solve's cost, plus a rebuild of the cached matrices).

    At normal incidence on a cell with the diagonal mirror x <-> y (rcwa.symmetry) only s is
    solved (E along y at phi = 0): the mirror maps it onto p (E along x) and order (m, n) onto
    (n, m), so p's efficiencies are s's with the orders swapped (half the cost; checked
    against a p solve by tests/rcwa/test_extrapolation_convergence.py).
    """
    if rule in ASR_RULES:
        return _solve_raw_asr(structure, direction, orders, ASR_RULES[rule])
    mirrored = direction.theta_deg == 0.0 and has_diagonal_mirror(structure)
    reset = _reset_peak_rss()
    start = time.perf_counter()
    if warm:
        prepare(structure, direction.wavelength_nm, (orders, orders), rule)
    warm_start = time.perf_counter()
    result = rcwa.solve(structure, direction.wavelength_nm, direction.theta_deg, direction.phi_deg, (orders, orders),
                        "s" if mirrored else "unpolarized", rule)
    end = time.perf_counter()
    peak = _peak_rss_bytes() if reset else None
    a = result.all_orders
    m, n = np.asarray(a["m"]), np.asarray(a["n"])
    R, T = np.array(a["R"]), np.array(a["T"])
    if mirrored:
        swap = np.lexsort((m, n))  # harmonic (n, m) for each (m, n) of the solver's order (m-major)
        R[:, 1], T[:, 1] = R[swap, 0], T[swap, 0]
    return _raw_solve(m, n, R, T, end - start, peak, end - warm_start if warm else None)


def _raw_solve(m: np.ndarray, n: np.ndarray, R: np.ndarray, T: np.ndarray, seconds: float, peak: int | None,
               warm_seconds: float | None) -> RawSolve:
    """A RawSolve from every harmonic's (m, n) and R, T per polarization (columns s, p): totals,
    and the orders that carry power on either side."""
    kept = np.flatnonzero((R.sum(axis=1) > 0) | (T.sum(axis=1) > 0))
    table = {(int(m[i]), int(n[i])): (float(R[i, 0]), float(R[i, 1]), float(T[i, 0]), float(T[i, 1])) for i in kept}
    return RawSolve((float(R[:, 0].sum()), float(R[:, 1].sum())), (float(T[:, 0].sum()), float(T[:, 1].sum())),
                    table, seconds, peak, warm_seconds)


def _solve_raw_asr(structure: Structure, direction: Direction, orders: int, in_plane_rule: str) -> RawSolve:
    """solve_raw for the ASR_RULES (rcwa.asr, both polarizations in one dense solve; nothing to
    prebuild, so its warm_seconds are its seconds)."""
    reset = _reset_peak_rss()
    start = time.perf_counter()
    result = solve_asr(structure, direction.wavelength_nm, direction.theta_deg, direction.phi_deg, orders, ASR_ETA,
                        in_plane_rule)
    seconds = time.perf_counter() - start
    peak = _peak_rss_bytes() if reset else None
    return _raw_solve(result.m, result.n, result.R, result.T, seconds, peak, seconds)


class SolveCache:
    """The raw solves of one structure in ``path`` (JSON), loaded on creation, written after each new solve."""

    def __init__(self, path: str | Path, structure: Structure) -> None:
        self.path = Path(path)
        self.structure = structure
        self._entries: dict[str, dict[str, Any]] = self._load()

    def _load(self) -> dict[str, dict[str, Any]]:
        if not self.path.exists():
            return {}
        data = json.loads(self.path.read_text())
        if data.get("format") != CACHE_FORMAT:
            raise ValueError(f"{self.path}: format: expected {CACHE_FORMAT}, got {data.get('format')!r}")
        return dict(data["entries"])

    def _key(self, direction: Direction, orders: int, rule: str) -> str:
        # ASR's entries carry its stretch, so a changed ASR_ETA never reuses them.
        named = f"{rule}@eta={ASR_ETA:g}" if rule in ASR_RULES else rule
        return f"{self.structure.content_hash}/{direction.key()}/{orders}/{named}"

    def get(self, direction: Direction, orders: int, rule: str) -> RawSolve | None:
        entry = self._entries.get(self._key(direction, orders, rule))
        return None if entry is None else RawSolve.from_json(entry)

    def solve(self, direction: Direction, orders: int, rule: str, *, warm: bool = False) -> RawSolve:
        """The cached solve, or a new one (written to the file before returning); ``warm``: one
        with its warm_seconds (solve_raw), solved again where the cached one lacks them."""
        cached = self.get(direction, orders, rule)
        if cached is not None and (cached.warm_seconds is not None or not warm):
            return cached
        raw = solve_raw(self.structure, direction, orders, rule, warm=warm)
        # Merged with what another process may have written meanwhile (the last writer wins per file, not per entry).
        self._entries = {**self._load(), **self._entries}
        self._entries[self._key(direction, orders, rule)] = {**raw.to_json(), "workbench": __version__}
        atomic_write_text(self.path, json.dumps({"format": CACHE_FORMAT, "structure": self.structure.name,
                                                 "entries": self._entries}))
        return raw

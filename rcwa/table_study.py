"""``workbench study rcwa``: what accuracy costs in time, for efficiency tables.

Three measured curves, written as JSON and CSV (for the HTML report) and plotted (PNG, SVG):

1. Truncation: the largest error of any kept order's efficiency against a converged
   reference (``reference_orders`` harmonics, Li's rule) versus retained harmonics, with
   seconds per solve, for Li's inverse rule and the Laurent rule.
2. Interpolation: the error of bilinear interpolation at random off-grid directions
   (against direct solves) versus angular step, for the paper's (theta, phi) grid and for
   a grid in direction cosines (u, v) = sin(theta) (cos phi, sin phi) with the same number
   of points, with the seconds and bytes a full table on that grid would take.
3. Presets: for each target error, the cheapest settings measured that reach it and
   their estimated full-table cost. Interpolation is judged by its RMS error over the
   test directions: its maximum sits on the kinks where an order appears or vanishes
   (Rayleigh anomalies), which no grid step smooths away; both are reported.
Efficiencies are unpolarized; errors are absolute (efficiencies are fractions of 1).

Measured on the CD (``make bench`` prints it): at equal numbers of points the (theta, phi)
grid interpolates better than direction cosines (RMS 0.0027 against 0.0050 at 2.5 deg), so
tables use the paper's (theta, phi) grid.

For a 2D cell (``run_convergence_study``) a 1D-style reference at hundreds of harmonics is
out of reach (N x N harmonics cost ~N^6), so the study is the accuracy-versus-time curve of
rcwa.convergence.accuracy_versus_time: each truncation's error against the limit
extrapolated from the truncations themselves (rcwa.extrapolation), for Li's rule, the
normal-vector rule and, for cells of rectangles, Li's rule with adaptive spatial resolution
(rcwa.asr, up to rcwa.convergence.ASR_MAX_ORDERS), versus seconds per solve and per table; written as
accuracy_time.csv, limits.csv, study_rcwa.json and study_rcwa.png/.svg. Its raw solves are
cached (rcwa.solve_cache), so a rerun with a higher ``max_orders`` solves only the new ones.
"""

from __future__ import annotations

import json
import math
import platform
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.interpolate import RegularGridInterpolator

import rcwa
from rcwa.convergence import CurveConfig, accuracy_versus_time
from rcwa.shapes import Rect
from rcwa.solve_cache import ASR_RULES, SolveCache
from rcwa.structure import Structure
from rcwa.sweep import sweep_directions
from workbench.core.files import atomic_write_csv, atomic_write_text
from workbench.core.plots import new_figure, save_figure
from workbench.core.version import versions

GRAZING_SIN = math.sin(math.radians(89.999))


@dataclass(frozen=True)
class StudyConfig:
    wavelengths_nm: tuple[float, ...] = (450.0, 550.0, 650.0)
    directions_deg: tuple[tuple[float, float], ...] = ((10.0, 20.0), (35.0, 60.0), (60.0, 5.0))
    orders: tuple[int, ...] = (11, 21, 31, 41, 61, 81)
    reference_orders: int = 241
    keep: int = 11
    interpolation_orders: int = 41
    steps_deg: tuple[float, ...] = (10.0, 5.0, 2.5, 1.25)
    test_points: int = 200
    table_wavelengths: int = 31
    targets: tuple[float, ...] = (1e-2, 3e-3, 1e-3)
    seed: int = 0


def truncation_study(structure: Structure, cfg: StudyConfig, bar: Any = None) -> list[dict]:
    """``bar``: a progress bar advanced once per solve (tqdm), or None."""
    tick = bar.update if bar is not None else (lambda n=1: None)
    reference = {}
    for wl in cfg.wavelengths_nm:
        for d in cfg.directions_deg:
            reference[wl, d] = _kept(rcwa.solve(structure, wl, *d, cfg.reference_orders, "unpolarized", "li"), cfg.keep)
            tick(1)
    rows = []
    for rule in ("li", "laurent"):
        for n in cfg.orders:
            errors, seconds = [], []
            for (wl, d), ref in reference.items():
                start = time.perf_counter()
                result = rcwa.solve(structure, wl, *d, n, "unpolarized", rule)
                seconds.append(time.perf_counter() - start)
                errors.append(np.max(np.abs(_kept(result, cfg.keep) - ref)))
                tick(1)
            rows.append({"rule": rule, "orders": n, "max_error": float(np.max(errors)),
                         "seconds_per_solve": float(np.median(seconds))})
    return rows


def _kept(result, keep: int) -> np.ndarray:
    m = result.all_orders["m"]
    mask = np.abs(m) <= keep // 2
    # R and T side by side, not summed: for a lossless cell with one propagating order R + T is 1 whatever the error
    return np.concatenate([result.all_orders["R"][mask].mean(axis=-1), result.all_orders["T"][mask].mean(axis=-1)])


def _unpolarized(sw) -> np.ndarray:
    return np.concatenate([sw.R.mean(axis=-1), sw.T.mean(axis=-1)], axis=-1)  # (P, 2K): R and T kept apart


def interpolation_study(structure: Structure, cfg: StudyConfig, bar: Any = None) -> list[dict]:
    """``bar``: a progress bar advanced once per grid step (tqdm), or None."""
    rng = np.random.default_rng(cfg.seed)
    wl = cfg.wavelengths_nm[len(cfg.wavelengths_nm) // 2]
    theta_t = np.degrees(np.arcsin(np.sqrt(rng.uniform(0, math.sin(math.radians(85.0)) ** 2, cfg.test_points))))
    phi_t = rng.uniform(0.0, 90.0, cfg.test_points)

    def unpolarized(theta_deg: np.ndarray, phi_deg: np.ndarray) -> np.ndarray:
        return _unpolarized(sweep_directions(structure, wl, theta_deg, phi_deg, orders=cfg.interpolation_orders, keep=cfg.keep))

    truth = unpolarized(theta_t, phi_t)
    rows = []
    for step in cfg.steps_deg:
        theta = np.append(np.arange(0.0, 90.0, step), 89.999) if 90.0 % step else np.arange(0.0, 90.0 + 1e-9, step)
        theta = np.minimum(theta, 89.999)
        phi = np.append(np.arange(0.0, 90.0, step), 90.0) if 90.0 % step else np.arange(0.0, 90.0 + 1e-9, step)
        th, ph = np.meshgrid(theta, phi, indexing="ij")
        start = time.perf_counter()
        grid = unpolarized(th.ravel(), ph.ravel()).reshape(th.shape + (-1,))
        seconds = time.perf_counter() - start
        guess = RegularGridInterpolator((theta, phi), grid)(np.stack([theta_t, phi_t], axis=1))
        rows.append(_row("theta-phi", step, th.size, seconds, guess - truth, cfg))
        n_side = int(round(math.sqrt(th.size)))  # the same number of points on a (u, v) lattice
        u = np.linspace(0.0, 1.0, n_side)
        U, V = np.meshgrid(u, u, indexing="ij")
        radius = np.hypot(U, V)
        scale = np.where(radius > GRAZING_SIN, GRAZING_SIN / np.maximum(radius, 1e-300), 1.0)
        th_c = np.degrees(np.arcsin(np.minimum(radius * scale, 1.0)))
        ph_c = np.degrees(np.arctan2(V, U))
        start = time.perf_counter()
        grid_c = unpolarized(th_c.ravel(), ph_c.ravel()).reshape(U.shape + (-1,))
        seconds_c = time.perf_counter() - start
        st = np.sin(np.radians(theta_t))
        points = np.stack([st * np.cos(np.radians(phi_t)), st * np.sin(np.radians(phi_t))], axis=1)
        guess_c = RegularGridInterpolator((u, u), grid_c)(points)
        rows.append(_row("direction-cosines", step, U.size, seconds_c, guess_c - truth, cfg))
        if bar is not None:
            bar.update(1)
    return rows


def _row(grid: str, step: float, points: int, seconds: float, error: np.ndarray, cfg: StudyConfig) -> dict:
    return {
        "grid": grid, "step_deg": step, "points": points, "max_error": float(np.max(np.abs(error))),
        "rms_error": float(np.sqrt(np.mean(error**2))),
        "table_seconds": seconds * cfg.table_wavelengths,
        "table_bytes": points * cfg.table_wavelengths * cfg.keep * 4,
    }


def recommend(truncation: list[dict], interpolation: list[dict], cfg: StudyConfig) -> list[dict]:
    """Cheapest measured (orders, grid, step) whose truncation error (max) and interpolation
    error (RMS) each stay below half the target; cost = full-table seconds scaled by the
    solve time at those orders."""
    out = []
    li = sorted((r for r in truncation if r["rule"] == "li"), key=lambda r: r["orders"])
    at_table_orders = [r for r in li if r["orders"] == cfg.interpolation_orders]
    base = at_table_orders[0] if at_table_orders else li[-1]
    for target in cfg.targets:
        orders = next((r for r in li if r["max_error"] <= target / 2), None)
        grids = sorted((r for r in interpolation if r["rms_error"] <= target / 2), key=lambda r: r["table_seconds"])
        if orders is None or not grids:
            out.append({"target_error": target, "reachable": False})
            continue
        g = grids[0]
        scale = orders["seconds_per_solve"] / base["seconds_per_solve"]
        out.append({"target_error": target, "reachable": True, "orders": orders["orders"], "grid": g["grid"],
                    "step_deg": g["step_deg"], "estimated_table_seconds": g["table_seconds"] * scale,
                    "table_bytes": g["table_bytes"]})
    return out


def study_steps(cfg: StudyConfig) -> int:
    """Units of work the progress bar counts: solves of the truncation study, grid steps."""
    points = len(cfg.wavelengths_nm) * len(cfg.directions_deg)
    return points * (1 + 2 * len(cfg.orders)) + len(cfg.steps_deg)


def run_study(structure: Structure, out: str | Path, cfg: StudyConfig = StudyConfig(), *, progress: bool = True) -> dict:
    from tqdm import tqdm  # deferred: start-up time

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with tqdm(total=study_steps(cfg), desc=f"study {structure.name}", unit="step", disable=not progress) as bar:
        truncation = truncation_study(structure, cfg, bar)
        interpolation = interpolation_study(structure, cfg, bar)
    presets = recommend(truncation, interpolation, cfg)
    data = {"structure": structure.name, "config": asdict(cfg), "truncation": truncation,
            "interpolation": interpolation, "presets": presets,
            "run": {"versions": versions("numpy", "scipy"), "machine": platform.machine(), "seconds": time.perf_counter() - start,
                    "structure_sha256": structure.content_hash}}
    atomic_write_text(out / "study_rcwa.json", json.dumps(data, indent=2))
    for name, rows in (("truncation", truncation), ("interpolation", interpolation), ("presets", presets)):
        atomic_write_csv(out / f"{name}.csv", rows)
    _plot(truncation, interpolation, out, structure.name)
    return data


def _plot(truncation: list[dict], interpolation: list[dict], out: Path, name: str) -> None:
    fig, axes = new_figure()
    for rule in ("li", "laurent"):
        rows = [r for r in truncation if r["rule"] == rule]
        axes[0].loglog([r["seconds_per_solve"] for r in rows], [r["max_error"] for r in rows], "o-",
                       label=f"{rule} rule")
        for r in rows:
            axes[0].annotate(str(r["orders"]), (r["seconds_per_solve"], r["max_error"]), fontsize=7)
    axes[0].set(xlabel="seconds per solve", ylabel="max error of kept orders", title=f"{name}: truncation (labels: harmonics)")
    for grid in ("theta-phi", "direction-cosines"):
        rows = [r for r in interpolation if r["grid"] == grid]
        (line,) = axes[1].loglog([r["table_seconds"] for r in rows], [r["max_error"] for r in rows], "s-", label=f"{grid} (max)")
        axes[1].loglog([r["table_seconds"] for r in rows], [r["rms_error"] for r in rows], "s--", color=line.get_color(),
                       alpha=0.6, label=f"{grid} (RMS)")
    axes[1].set(xlabel="full-table seconds (estimated)", ylabel="interpolation error (max, RMS)", title="bilinear interpolation")
    save_figure(fig, axes, out, "study_rcwa")


def run_convergence_study(structure: Structure, out: str | Path, cfg: CurveConfig, cache: SolveCache, *,
                          progress: bool = True) -> dict:
    """The 2D accuracy-versus-time study (module docstring); ``cache`` holds the raw solves."""
    from tqdm import tqdm  # deferred: start-up time

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    if any(not isinstance(shape, Rect) for layer in structure.layers for shape in layer.shapes_2d):
        cfg = replace(cfg, rules=tuple(r for r in cfg.rules if r not in ASR_RULES))  # ASR stretches rectangles only
    steps = len(cfg.directions) * sum(len(cfg.orders(rule)) for rule in cfg.rules)
    with tqdm(total=steps, desc=f"study {structure.name}", unit="solve", disable=not progress) as bar:
        curve = accuracy_versus_time(structure, cache, cfg, bar)
    data = {"structure": structure.name, "config": asdict(cfg), **curve, "solve_cache": str(cache.path),
            "run": {"versions": versions("numpy", "scipy"), "machine": platform.machine(),
                    "seconds": time.perf_counter() - start, "structure_sha256": structure.content_hash}}
    atomic_write_text(out / "study_rcwa.json", json.dumps(data, indent=2))
    atomic_write_csv(out / "accuracy_time.csv", curve["rows"])
    atomic_write_csv(out / "limits.csv", curve["limits"])
    _plot_convergence(curve, cfg, out, structure.name)
    return data


def _plot_convergence(curve: dict, cfg: CurveConfig, out: Path, name: str) -> None:
    fig, axes = new_figure()
    styles = {"T_total": "o-", "T00": "s--"}
    for ax, column, label in ((axes[0], "seconds_per_solve", "seconds per solve (mean over the directions)"),
                              (axes[1], "seconds_per_table", f"seconds per {cfg.preset}-preset table, one core")):
        for rule, colour in zip(cfg.rules, ("C0", "C1", "C2", "C3"), strict=False):
            rows = [r for r in curve["rows"] if r["rule"] == rule]
            for q, style in styles.items():
                ys = [max(r[f"error_{q}"], 1e-6) for r in rows]
                ax.loglog([r[column] for r in rows], ys, style, color=colour, label=f"{rule}: {q}")
            for r in rows:
                ax.annotate(str(r["orders"]), (r[column], max(r["error_T_total"], 1e-6)), fontsize=7)
        for q, ls in (("T_total", "-"), ("T00", "--")):
            ax.axhline(curve["reference_errors"][q], color="grey", ls=ls, lw=0.8, label=f"{q} limit's error bar")
        ax.set(xlabel=label, ylabel="max |efficiency - extrapolated limit|")
    axes[0].set_title(f"{name}: truncation N x N (labels: N)")
    axes[1].set_title("per table (beyond the timed N: estimated)")
    save_figure(fig, axes, out, "study_rcwa")

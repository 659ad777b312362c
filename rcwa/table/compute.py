"""One chunk of a table: the efficiencies of the kept orders at one wavelength over the
table's (theta, phi) grid, from rcwa.sweep; for light from above and, with ``both_sides``,
from below (the z-inverted structure, [Lange 2021, Sec. 2.2], for see-through
elements).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from rcwa.structure import Layer, Structure
from rcwa.sweep import sweep_directions
from rcwa.table.settings import GRAZING_THETA_DEG, TableSettings, transmits


def compute_chunk(structure: Structure, settings: TableSettings, wavelength_nm: float,
                  threads: int, mask: np.ndarray | None = None) -> tuple[dict[str, np.ndarray], tuple[int, int, int]]:
    """All arrays of one wavelength: R (and T; and from below), (theta, phi, order, pol);
    and the sweeps' (eigen-solves, refined eigen-solves, directions solved in mirror
    sectors: a 2D cell's in its mirror planes, rcwa.sweep).

    ``mask`` (theta, phi) of a planned table: the nodes solved with the table's orders;
    the rest with ``settings.fill_orders``.
    """
    th, ph = np.meshgrid(clamped(settings.theta_deg), np.array(settings.phi_deg), indexing="ij")
    exact = np.ones(th.size, bool) if mask is None else np.asarray(mask, bool).ravel()
    groups = [(exact, settings.orders), (~exact, settings.fill_orders or settings.orders)]
    values: dict[str, np.ndarray] = {}
    counts = np.zeros(3, int)
    for nodes, orders in groups:
        if not nodes.any():
            continue
        part, done = solve_directions(structure, settings, wavelength_nm, th.ravel()[nodes], ph.ravel()[nodes], orders,
                                      settings.factorization, threads)
        counts += done
        for name, array in part.items():
            values.setdefault(name, np.empty((th.size,) + array.shape[1:], np.float32))[nodes] = array
    out = {name: whole.reshape(th.shape + whole.shape[1:]) for name, whole in values.items()}
    return out, (int(counts[0]), int(counts[1]), int(counts[2]))


def clamped(theta_deg) -> np.ndarray:
    """The polar angles solved for a table's: theta = 90 deg at GRAZING_THETA_DEG."""
    return np.array([min(t, GRAZING_THETA_DEG) for t in theta_deg])


def solve_directions(structure: Structure, settings: TableSettings, wavelength_nm: float, theta_deg: np.ndarray,
                     phi_deg: np.ndarray, orders: tuple[int, ...], factorization: str,
                     threads: int) -> tuple[dict[str, np.ndarray], tuple[int, int, int]]:
    """The table's arrays (its sides, its polarizations, float32) at the P directions given,
    solved with ``orders`` and ``factorization`` in one sweep per side (rcwa.sweep):
    name -> (P, kept order, pol); and the sweeps' counts as compute_chunk's."""
    out, solves, refined, sectors = {}, 0, 0, 0
    sides = [("", structure)] + ([("_below", flipped(structure))] if settings.both_sides else [])
    for suffix, s in sides:
        sw = sweep_directions(s, wavelength_nm, theta_deg, phi_deg, orders, keep=settings.keep,
                              factorization=factorization, threads=threads)
        solves, refined, sectors = solves + sw.eigen_solves, refined + sw.eigen_refined, sectors + sw.sector_points
        for name, whole in (("R", sw.R), ("T", sw.T)):
            if name == "T" and (settings.reflection_only or not transmits(s, settings)):
                continue
            out[name + suffix] = _select_pol(whole, settings.pol).astype(np.float32)
    return out, (solves, refined, sectors)


def _select_pol(values: np.ndarray, pol: str) -> np.ndarray:
    unpolarized = values.mean(axis=-1, keepdims=True)
    return {"s": values[..., :1], "p": values[..., 1:], "unpolarized": unpolarized,
            "all": np.concatenate([values, unpolarized], axis=-1)}[pol]


def flipped(structure: Structure) -> Structure:
    """The z-inverted structure: light from below sees the substrate as its superstrate."""
    layers = tuple(Layer(layer.thickness, layer.material, layer.shapes, layer.name) for layer in reversed(structure.layers))
    return replace(structure, superstrate=structure.substrate, substrate=structure.superstrate, layers=layers)

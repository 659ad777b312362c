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


def flipped(structure: Structure) -> Structure:
    """The z-inverted structure: light from below sees the substrate as its superstrate."""
    layers = tuple(Layer(layer.thickness, layer.material, layer.shapes, layer.name) for layer in reversed(structure.layers))
    return replace(structure, superstrate=structure.substrate, substrate=structure.superstrate, layers=layers)

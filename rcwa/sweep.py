"""Sweeps: efficiencies of kept orders for many incident directions and wavelengths.

The Fourier matrices of every layer depend on the wavelength only, so they are built
once per wavelength (rcwa.solver.prepare); the C++ core then solves all directions on
``threads`` threads, sharing each 1D layer's eigen-solve among the directions with the
same k_x (its eigenvectors do not depend on k_y; rcwa/cpp/lamellar.cpp), and refining
each k_x's eigen-solve from its neighbour's (rcwa/cpp/sweep.hpp). Directions that respect
a mirror of a 2D cell (k_x = 0 for x -> -x, k_y = 0 for y -> -y: phi = 0, 90, 180, 270,
and normal incidence) are solved in mirror-symmetry sectors (rcwa/cpp/sectors.hpp). A
sweep otherwise runs the same code as a single solve; they agree to 1e-13
(tests/rcwa/test_sweep.py), and the sectors the general path to 1e-12
(tests/rcwa/test_sectors.py).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rcwa import _core
from rcwa.solver import mirrors_of, prepare, stack_method
from rcwa.structure import Structure
from workbench.core.conventions import incident_tangential_k
from workbench.core.errors import UserInputError


@dataclass(frozen=True)
class DirectionSweep:
    """Efficiencies of the kept orders at one wavelength for P incident directions.

    R, T: (P, K, 2) for s and p incidence (last axis); the unpolarized efficiency is their
    mean. ``m``, ``n``: the kept orders (K). ``kx0``, ``ky0``: incident tangential wave
    vectors divided by k0 (P). T is zero over an absorbing substrate. ``eigen_solves``:
    the 1D layers' eigen-solves, ``eigen_refined`` of them refined from a neighbouring
    k_x's eigenvectors instead of solved afresh (rcwa/cpp/sweep.hpp). ``sector_points``:
    the directions solved in mirror-symmetry sectors (rcwa/cpp/sectors.hpp).
    """

    wavelength_nm: float
    m: np.ndarray
    n: np.ndarray
    kx0: np.ndarray
    ky0: np.ndarray
    R: np.ndarray
    T: np.ndarray
    eigen_solves: int = 0
    eigen_refined: int = 0
    sector_points: int = 0


def default_threads() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def kept_harmonics(m: np.ndarray, n: np.ndarray, keep: Sequence[int]) -> np.ndarray:
    """Indices of the harmonics with |m| <= keep_x // 2 (and |n| <= keep_y // 2)."""
    half = [k // 2 for k in keep]
    mask = np.abs(m) <= half[0]
    if len(half) > 1:
        mask &= np.abs(n) <= half[1]
    return np.flatnonzero(mask)


def sweep_directions(
    structure: Structure,
    wavelength_nm: float,
    theta_deg: np.ndarray,
    phi_deg: np.ndarray,
    orders: int | Sequence[int],
    keep: int | Sequence[int] | None = None,
    factorization: str = "auto",
    stack: str = "etm",
    threads: int | None = None,
    sectors: bool = True,
) -> DirectionSweep:
    """Solve ``structure`` at one wavelength for every (theta, phi) pair given.

    ``keep``: the kept orders per direction (odd, at most ``orders``), symmetric about 0;
    default: all retained harmonics. ``sectors``: solve the directions that respect a
    mirror of a 2D cell in mirror-symmetry sectors (False: the general path everywhere,
    to check them or time them).
    """
    method = stack_method(stack)
    theta = np.radians(np.asarray(theta_deg, dtype=float).ravel())
    phi = np.radians(np.asarray(phi_deg, dtype=float).ravel())
    if theta.shape != phi.shape:
        raise UserInputError("theta and phi must pair up", field="directions", got=(theta.size, phi.size))
    if np.any(theta < 0) or np.any(theta >= math.pi / 2):
        raise UserInputError("the polar angle must be in [0, 90) degrees", field="theta", got=float(np.degrees(theta.max())))
    prep = prepare(structure, wavelength_nm, orders, factorization)
    keep_counts = prep.counts if keep is None else _keep_counts(keep, prep.counts)
    idx = kept_harmonics(prep.harmonics.m, prep.harmonics.n, keep_counts)
    n_sup = math.sqrt(prep.eps_sup.real)
    kx0, ky0 = incident_tangential_k(n_sup, theta, phi)
    sol = _core.sweep(
        prep.dkx, prep.dky, prep.zero, prep.eps_sup, prep.eps_sub, prep.core_layers,
        kx0, ky0, -np.sin(phi), np.cos(phi), [int(i) for i in idx], method, threads or default_threads(),
        mirrors_of(prep) if sectors else [],
    )
    # The incident wave's kz is the specular order's, from the core (its outgoing branch,
    # workbench.core.conventions.kz_branch), as in a single solve (rcwa/cpp/efficiency.hpp).
    R, T, _ = sol.efficiencies(int(np.flatnonzero(idx == prep.zero)[0]), prep.eps_sup, prep.eps_sub)
    return DirectionSweep(float(wavelength_nm), prep.harmonics.m[idx], prep.harmonics.n[idx], kx0, ky0, R, T,
                          sol.eigen_solves, sol.eigen_refined, sol.sector_points)


def _keep_counts(keep: int | Sequence[int], counts: tuple[int, ...]) -> tuple[int, ...]:
    values = (keep,) * len(counts) if isinstance(keep, (int, np.integer)) else tuple(keep)
    if len(values) != len(counts) or any(
        isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1 or v % 2 == 0 or v > c
        for v, c in zip(values, counts, strict=True)
    ):
        raise UserInputError(
            "kept orders must be odd, one count per direction, and at most the retained orders",
            field="keep-orders", expected=f"odd counts <= {list(counts)}", got=keep,
        )
    return tuple(int(v) for v in values)

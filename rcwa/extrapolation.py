"""Extrapolation of a quantity computed at increasing truncation N to N -> infinity, with an error bar.

RCWA efficiencies converge in the number of retained harmonics N (per direction) like a
power law, v(N) = v_inf + b N^-p, with p set by the field's singularities at the
structure's edges and corners (Li's rule on a metal block: p ~ 1-2; the Laurent rule
and a badly factorized rule: p <= 1) [Li 1997, Sec. 5; Lalanne 1996, Fig. 2]. The limit is
found as in Richardson extrapolation [Richardson 1927; Press 2007, Sec. 5.4] but from a
least-squares fit over several truncations rather than two, so that the fit's residual
measures how well the power law holds:

* ``fit_power_law``: v = a + b_g N^-p (one amplitude b_g per group g of points) by
  variable projection (for each p the best a, b_g are a linear least-squares problem; p
  is found by a bounded one-dimensional search over the residual), with the standard
  error of a from the linearized covariance s^2 (J^T J)^-1 of the model's Jacobian J in
  (a, b_g, p) at the fit (s^2 the residual's variance over the degrees of freedom left)
  [Golub 1973; Press 2007, Sec. 15.5].
* Oscillating sequences. A rectangular block whose width is half the period has Fourier
  coefficients that vanish at even indices, so truncations whose largest harmonic index
  M = (N - 1) / 2 is even and those where it is odd converge on different curves, often
  from opposite sides (gold2d, Li's rule: T_total 0.269, 0.286, 0.274, 0.283, ... at
  N = 9, 11, 13, 15). ``extrapolate`` fits the classes of ``(N - 1) / 2 mod stride``
  jointly: one limit and one power, an amplitude per class. (Fitting each class alone
  doubles the free parameters; on gold2d a flat class, such as Li's odd-M T_total at
  0.2806 from N = 27 to 47, then leaves the power to the other class alone and the two
  limits scatter by more than their gap.)
* ``extrapolate``: the estimate is the joint free-power fit over the last ``tail``
  truncations of every class; the error is twice its standard error of the limit, plus
  the largest excess, beyond its own two standard errors, of any other extrapolation
  choice's distance from the estimate. The choices: the joint fit over fewer of the last
  truncations (down to one degree of freedom left), each class fitted alone (so classes
  that disagree widen the bar), and the two-point Richardson limit of each class's last
  two truncations with the fitted power (taken as exact). A short window's fit scatters
  with the data's noise and says so by its standard error; only a disagreement larger
  than that says the power law fails over the window, and only that widens the bar. Fits
  with a fixed power are not among the choices: a wrong fixed power biases the limit by
  far more than the data's scatter (a true p = 1.7 fitted with p = 1 or 2 moves the limit
  by 1e-3 at N <= 35), so they would measure the choice, not the data. The error is thus
  "how much the answer moves when the extrapolation is done differently", not a
  statistical confidence interval; a power at the search's bound (``power_at_bound``)
  says the sequence is not yet in its power-law regime, and its bar is not to be trusted.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize_scalar

POWER_BOUNDS = (0.3, 6.0)  # the free power's search range (a convergence order outside it is not a power law)
MIN_POINTS_FREE = 3  # a, b and p: at least three points (a residual needs four)


@dataclass(frozen=True)
class PowerLawFit:
    """v(N) = limit + amplitudes[g] * N^-power fitted to ``orders``, ``values`` (g: the point's group)."""

    limit: float
    amplitudes: tuple[float, ...]
    power: float
    residual_rms: float  # RMS of the fit's residuals
    limit_stderr: float  # standard error of the limit (nan with no degree of freedom left)
    orders: tuple[int, ...]
    power_free: bool

    @property
    def amplitude(self) -> float:
        return self.amplitudes[0]

    @property
    def power_at_bound(self) -> bool:
        """The free power ran into POWER_BOUNDS: the data do not look like a power law."""
        return self.power_free and min(abs(self.power - b) for b in POWER_BOUNDS) < 1e-3


def _linear_fit(n: np.ndarray, v: np.ndarray, groups: np.ndarray, power: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Least squares of v = a + b_g n^-power: coefficients (a, b_0, b_1, ...), the design matrix, the residual sum
    of squares."""
    columns = [np.ones_like(n)] + [np.where(groups == g, n ** (-power), 0.0) for g in range(int(groups.max()) + 1)]
    design = np.column_stack(columns)
    coef, *_ = np.linalg.lstsq(design, v, rcond=None)
    return coef, design, float(np.sum((design @ coef - v) ** 2))


def fit_power_law(orders: Sequence[int] | np.ndarray, values: Sequence[float] | np.ndarray,
                  power: float | None = None, groups: Sequence[int] | np.ndarray | None = None) -> PowerLawFit:
    """Fit ``values = a + b_g orders^-p`` (``power`` fixed, or free within POWER_BOUNDS; one
    amplitude b_g per group 0, 1, ... of ``groups``, default one group) by variable
    projection [Golub 1973]; module docstring."""
    n, v = np.asarray(orders, dtype=float), np.asarray(values, dtype=float)
    g = np.zeros(n.size, dtype=int) if groups is None else np.asarray(groups, dtype=int)
    count = int(g.max()) + 1 if g.size else 1
    need = count + 1 + (power is None)
    if n.size != v.size or g.shape != n.shape or n.size < need or np.any(n <= 0) or not np.all(np.isfinite(v)):
        raise ValueError(f"fit_power_law: expected >= {need} finite values at positive orders, got {n.size} orders, "
                         f"{v.size} values")
    if power is None:
        # The residual is not unimodal in p in general: a coarse grid first, then a bounded refinement around its best.
        grid = np.geomspace(*POWER_BOUNDS, 61)
        best = int(np.argmin([_linear_fit(n, v, g, p)[2] for p in grid]))
        lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, grid.size - 1)]
        found = minimize_scalar(lambda p: _linear_fit(n, v, g, p)[2], bounds=(lo, hi), method="bounded",
                                options={"xatol": 1e-6})
        p = float(found.x)
    else:
        p = float(power)
    coef, design, ssr = _linear_fit(n, v, g, p)
    if power is None:  # the Jacobian of a + b_g N^-p in (a, b_g, p): the limit's error includes the power's
        design = np.column_stack([design, -coef[1 + g] * np.log(n) * n ** (-p)])
    dof = n.size - design.shape[1]
    stderr = math.sqrt(ssr / dof * np.linalg.pinv(design.T @ design)[0, 0]) if dof > 0 else math.nan
    return PowerLawFit(float(coef[0]), tuple(float(c) for c in coef[1:]), p, math.sqrt(ssr / n.size), stderr,
                       tuple(int(x) for x in orders), power is None)


def richardson(n1: int, v1: float, n2: int, v2: float, power: float) -> float:
    """Two-point Richardson limit of v = a + b N^-power from (n1, v1) and (n2, v2) [Richardson 1927]."""
    w1, w2 = float(n1) ** power, float(n2) ** power
    return (w2 * v2 - w1 * v1) / (w2 - w1)


def classes(orders: Sequence[int], stride: int) -> list[list[int]]:
    """Indices of ``orders`` split by ``((N - 1) / 2) mod stride`` (largest harmonic index's residue), each ascending in N."""
    groups: dict[int, list[int]] = {}
    for i in sorted(range(len(orders)), key=lambda i: orders[i]):
        groups.setdefault(((orders[i] - 1) // 2) % stride, []).append(i)
    return [groups[k] for k in sorted(groups)]


@dataclass(frozen=True)
class Extrapolation:
    """The limit of a truncation sequence with its error bar (module docstring) and what went into it."""

    value: float
    error: float
    fit: PowerLawFit  # the primary fit: every class's last ``tail`` truncations, one limit and power, one amplitude each
    choices: dict[str, float] = field(default_factory=dict)  # every extrapolation choice's limit, by name
    last_value: float = math.nan  # the value at the highest truncation

    @property
    def interval(self) -> tuple[float, float]:
        return self.value - self.error, self.value + self.error


def _tails(o: np.ndarray, split: list[list[int]], count: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the last ``count`` truncations of every class, and each one's class number."""
    picked = [(i, k) for k, g in enumerate(split) for i in g[-count:]]
    return np.array([i for i, _ in picked]), np.array([k for _, k in picked])


def extrapolate(orders: Sequence[int], values: Sequence[float], *, stride: int = 2, tail: int = 5) -> Extrapolation:
    """The N -> infinity limit of ``values`` at ``orders`` (odd truncations), each residue class of
    ``(N - 1) / 2 mod stride`` with its own amplitude (``stride=1``: one sequence); module docstring."""
    if len(orders) != len(values):
        raise ValueError(f"extrapolate: {len(orders)} orders but {len(values)} values")
    o, v = np.asarray(orders), np.asarray(values, dtype=float)
    split = classes(list(orders), stride)
    if any(len(g) < MIN_POINTS_FREE + 1 for g in split):
        raise ValueError(f"extrapolate: each of the {len(split)} classes of (N - 1)/2 mod {stride} needs at least "
                         f"{MIN_POINTS_FREE + 1} truncations, got {[len(g) for g in split]}")
    top = min([tail] + [len(g) for g in split])
    rows, groups = _tails(o, split, top)
    main = fit_power_law(o[rows], v[rows], groups=groups)
    choices: dict[str, tuple[float, float]] = {}  # name -> (limit, standard error)
    for count in range(1 + math.ceil(3 / len(split)), top):  # a degree of freedom left: G * count > G + 2
        r, r_groups = _tails(o, split, count)
        fit = fit_power_law(o[r], v[r], groups=r_groups)
        choices[f"joint, last {count}"] = (fit.limit, fit.limit_stderr)
    for k, members in enumerate(split):
        n_k, v_k = o[members], v[members]
        if len(split) > 1:
            own = fit_power_law(n_k[-top:], v_k[-top:])
            choices[f"class {k} alone, last {top}"] = (own.limit, own.limit_stderr)
        choices[f"class {k}: Richardson, last 2"] = (
            richardson(int(n_k[-2]), v_k[-2], int(n_k[-1]), v_k[-1], main.power), 0.0)
    statistical = 2 * main.limit_stderr if math.isfinite(main.limit_stderr) else 0.0
    excess = max(abs(c - main.limit) - (2 * e if math.isfinite(e) else 0.0) for c, e in choices.values())
    return Extrapolation(main.limit, statistical + max(excess, 0.0), main, {k: c for k, (c, _) in choices.items()},
                         float(v[np.argmax(o)]))

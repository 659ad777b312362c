"""The truncation extrapolation (rcwa.extrapolation) on synthetic sequences with a known limit,
and the raw-solve cache of the convergence study (rcwa.solve_cache).

Synthetic sequences v(N) = a + b N^-p at the odd truncations 9..35 the gold2d study uses:
* exact data: the fit must return a, b and p to round-off (TOL_EXACT = 1e-9; the
  variable projection's search stops at xatol 1e-6 in p, which moves a by < 1e-9 here);
* with noise of standard deviation NOISE = 1e-5 (SEEDS = 40 draws), the true limit must
  lie within the error bar in at least MIN_COVERAGE = 90 % of the draws (measured 39 of
  40: the bar's statistical part is two standard errors), and the bar must stay well
  inside the last truncation's own error, or extrapolating would gain nothing: median
  below 0.3 of it, none above 1.5 (measured 0.18 and 0.99);
* an oscillating sequence (even and odd M = (N - 1) / 2 approaching from opposite sides,
  as Li's rule does on gold2d): fitted with one amplitude per residue class the limit must
  come out to TOL_OSCILLATING = 1e-6 with both amplitudes right, while fitting all
  truncations as one sequence does not get within 100 x that (the contrast that makes the
  class split necessary).
"""

import math

import numpy as np
import pytest

import rcwa
from rcwa import solve_cache
from rcwa.extrapolation import classes, extrapolate, fit_power_law, richardson
from rcwa.solve_cache import Direction, SolveCache, solve_raw

ORDERS = list(range(9, 37, 2))
LIMIT, AMPLITUDE, POWER = 0.2795, -0.9, 1.7
TOL_EXACT = 1e-9
NOISE = 1e-5
SEEDS = 40
MIN_COVERAGE = 0.9
TOL_OSCILLATING = 1e-6


def _sequence(orders, wiggle=0.0, noise=0.0, seed=0):
    n = np.asarray(orders, dtype=float)
    sign = np.where(((n - 1) // 2) % 2 == 0, 1.0, -1.0)
    rng = np.random.default_rng(seed)
    return LIMIT + (AMPLITUDE + wiggle * sign) * n**-POWER + noise * rng.standard_normal(n.size)


def test_power_law_fit_recovers_exact_parameters():
    fit = fit_power_law(ORDERS, _sequence(ORDERS))
    assert fit.limit == pytest.approx(LIMIT, abs=TOL_EXACT)
    assert fit.amplitude == pytest.approx(AMPLITUDE, rel=1e-6)
    assert fit.power == pytest.approx(POWER, abs=1e-5)
    assert fit.residual_rms < TOL_EXACT and not fit.power_at_bound


def test_fixed_power_fit_and_richardson_are_exact_for_their_own_power():
    values = _sequence(ORDERS)
    assert fit_power_law(ORDERS, values, power=POWER).limit == pytest.approx(LIMIT, abs=1e-12)
    assert richardson(ORDERS[-2], values[-2], ORDERS[-1], values[-1], POWER) == pytest.approx(LIMIT, abs=1e-12)
    # the wrong power leaves a bias: what the spread between choices measures
    assert abs(fit_power_law(ORDERS[-3:], values[-3:], power=1.0).limit - LIMIT) > 1e-4


def test_noisy_sequences_limit_lies_within_the_error_bar():
    inside, ratios = 0, []
    for seed in range(SEEDS):
        result = extrapolate(ORDERS, _sequence(ORDERS, noise=NOISE, seed=seed), stride=1, tail=8)
        inside += abs(result.value - LIMIT) <= result.error
        ratios.append(result.error / abs(result.last_value - LIMIT))
    assert inside >= MIN_COVERAGE * SEEDS, inside
    assert np.median(ratios) < 0.3 and max(ratios) < 1.5, (np.median(ratios), max(ratios))


def test_oscillating_sequence_needs_the_residue_classes():
    values = _sequence(ORDERS, wiggle=1.5)
    split = extrapolate(ORDERS, values, stride=2)
    assert split.value == pytest.approx(LIMIT, abs=TOL_OSCILLATING)
    assert split.error < 1e-5  # exact data: every choice with the right power agrees; fixed wrong powers stay small
    assert split.fit.power == pytest.approx(POWER, abs=1e-4)
    assert split.fit.amplitudes == pytest.approx([AMPLITUDE + 1.5, AMPLITUDE - 1.5], rel=1e-6)
    whole = extrapolate(ORDERS, values, stride=1)
    assert abs(whole.value - LIMIT) > 100 * TOL_OSCILLATING


def test_classes_split_by_largest_harmonic_index():
    assert classes([9, 11, 13, 15, 17], 2) == [[0, 2, 4], [1, 3]]  # M = 4, 6, 8 | 5, 7
    assert classes([15, 9, 11, 13], 1) == [[1, 2, 3, 0]]


def test_bad_input_is_refused_with_a_message():
    with pytest.raises(ValueError, match="fit_power_law"):
        fit_power_law([9, 11], [0.1, 0.2])
    with pytest.raises(ValueError, match="classes"):
        extrapolate([9, 11, 13, 15, 17], [0.1] * 5, stride=2)  # two classes of 3 and 2 points
    with pytest.raises(ValueError, match="orders but"):
        extrapolate([9, 11], [0.1])
    assert math.isnan(fit_power_law([9, 11, 13], [0.3, 0.29, 0.285]).limit_stderr)  # no degree of freedom left


def test_normal_incidence_p_from_the_diagonal_mirror_equals_a_p_solve():
    """solve_raw solves only s at normal incidence on gold2d and maps it onto p by the diagonal
    mirror ((m, n) -> (n, m)); a real unpolarized solve must agree per order to round-off (1e-12)."""
    s = rcwa.load_structure("gold2d")
    raw = solve_raw(s, Direction(550.0, 0.0), 7, "li")
    full = rcwa.solve(s, 550.0, 0.0, 0.0, (7, 7), "unpolarized", "li").all_orders
    for i, (m, n) in enumerate(zip(full["m"].tolist(), full["n"].tolist(), strict=True)):
        expected = (*full["R"][i], *full["T"][i])
        assert raw.orders.get((m, n), (0.0,) * 4) == pytest.approx(expected, abs=1e-12)
    assert raw.T_total[1] == pytest.approx(float(full["T"][:, 1].sum()), abs=1e-12)


def test_cache_returns_stored_solves_without_solving(tmp_path, monkeypatch):
    s = rcwa.load_structure("gold2d")
    path = tmp_path / "raw.json"
    first = SolveCache(path, s).solve(Direction(550.0, 30.0), 5, "li")

    def no_solve(*args, **kwargs):
        raise AssertionError("solved again")

    monkeypatch.setattr(solve_cache, "solve_raw", no_solve)
    again = SolveCache(path, s).solve(Direction(550.0, 30.0), 5, "li")
    assert again.T_total == first.T_total and again.orders == first.orders
    assert SolveCache(path, s).get(Direction(550.0, 30.0), 7, "li") is None
    assert SolveCache(path, rcwa.load_structure("cd")).get(Direction(550.0, 30.0), 5, "li") is None

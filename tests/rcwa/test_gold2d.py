"""The paper's 2D gold block (built-in gold2d): symmetry and convergence.

* Symmetry: the cell is four-fold symmetric, so at normal incidence x- and y-polarized
  light give the same totals. Asserted to 1e-6 as the issue asks (measured: round-off,
  1e-15, for every rule, since each rule treats x and y alike).
* Convergence: zero-order transmission at 550 nm. Asserted: between 11 x 11 and 15 x 15
  harmonics Li's 1997 rule moves by less than GOLD2D_LI_STEP (measured 0.0044, while the
  Laurent rule still jumps by 0.02-0.2 between successive truncations); its value is
  close to the value at 19 x 19 (slow test). `python -m benchmarks.bench_convergence` (make bench) prints the curve.
"""

import pytest

import rcwa

TOLERANCE_SYMMETRY = 1e-6
GOLD2D_LI_STEP = 0.01


@pytest.mark.parametrize("rule", ["li", "nv", "laurent"])
def test_x_and_y_polarization_give_equal_totals(rule):
    s = rcwa.load_structure("gold2d")
    y_pol = rcwa.solve(s, 550.0, 0.0, 0.0, (7, 7), "s", rule)  # s at phi = 0: E along y
    x_pol = rcwa.solve(s, 550.0, 0.0, 90.0, (7, 7), "s", rule)  # s at phi = 90: E along -x
    assert x_pol.R_total == pytest.approx(y_pol.R_total, abs=TOLERANCE_SYMMETRY)
    assert x_pol.T_total == pytest.approx(y_pol.T_total, abs=TOLERANCE_SYMMETRY)
    assert x_pol.order(0, 0).T == pytest.approx(y_pol.order(0, 0).T, abs=TOLERANCE_SYMMETRY)


def test_li_rule_settles_between_11_and_15_orders():
    s = rcwa.load_structure("gold2d")
    t11 = rcwa.solve(s, 550.0, 0.0, 0.0, (11, 11), "s", "li").order(0, 0).T
    t15 = rcwa.solve(s, 550.0, 0.0, 0.0, (15, 15), "s", "li").order(0, 0).T
    assert abs(t15 - t11) < GOLD2D_LI_STEP
    laurent = [rcwa.solve(s, 550.0, 0.0, 0.0, (n, n), "s", "laurent").order(0, 0).T for n in (11, 13, 15)]
    assert max(laurent) - min(laurent) > 5 * GOLD2D_LI_STEP  # the contrast that makes the test meaningful


@pytest.mark.slow
def test_li_rule_at_19_orders_agrees_with_15():
    s = rcwa.load_structure("gold2d")
    t15 = rcwa.solve(s, 550.0, 0.0, 0.0, (15, 15), "s", "li").order(0, 0).T
    t19 = rcwa.solve(s, 550.0, 0.0, 0.0, (19, 19), "s", "li").order(0, 0).T
    assert abs(t19 - t15) < 0.005

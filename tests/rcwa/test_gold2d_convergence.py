"""gold2d's converged values (rcwa.gold2d_converged) and the 2D accuracy-versus-time study.

* ``reverse_direction`` follows the grating equation: order (1, 0) of the forward incidence
  and the returning order of the reverse one have opposite tangential wave vectors (up to
  the x mirror), to round-off.
* The 2D study (slow, ~15 s): on a small configuration its files hold what it says, Li's
  rule converges (its error at 23 x 23 is below a third of its error at 9 x 9: measured
  0.0018 against 0.026 at normal incidence) and the table cost beyond the timed
  truncations is marked as estimated.
* Heavy (an hour on 2 cores with a cold raw-solve cache; set RCWA_CONVERGENCE_CACHE to a
  folder holding gold2d_raw.json to reuse one): the converged values published in
  docs/gold2d_convergence.md come out again, each within a tenth of its own error bar
  (the solves are deterministic; the bar is what extrapolation leaves uncertain),
  reciprocity holds within the stated errors, and the issue's bar at 550 nm, normal
  incidence: T_total from both rules within 0.003 with overlapping bars (met); T(0,0)
  likewise (not met: a strict xfail that fails once it is). Adaptive spatial resolution's
  values (rcwa.asr, N <= 35, about 20 minutes cold; the NV rule's in the same coordinates at
  normal incidence, about 10 more) come out again, reciprocity holds on them, Li's rule
  agrees with them at 550 nm, normal incidence, on T_total and T(0,0) within 0.003 with
  overlapping bars (measured 0.0010 and 0.0009), and so do the two rules in stretched
  coordinates, the issue's bar (measured 0.0015 and 0.0007).
"""

import csv
import json
import math

import pytest

import rcwa
from rcwa import gold2d_converged as g2
from rcwa.convergence import CurveConfig
from rcwa.solve_cache import Direction, SolveCache
from rcwa.table_study import run_convergence_study
from workbench.core.conventions import ORDER_SIGN

RECIPROCITY_BAR = 1e-3
ISSUE_GAP = 0.003  # issue 29: both rules' T_total and T(0,0) at 550 nm, normal incidence, this close
# (nm, theta, pol, quantity, rule) -> (value, error) as docs/gold2d_convergence.md publishes them
# (`python -m benchmarks.bench_convergence --published-literal` prints this dict)
PUBLISHED: dict[tuple[float, float, str, str, str], tuple[float, float]] = {
    (450.0, 0.0, 's', 'T_total', 'li'): (0.342849, 0.000320),
    (450.0, 0.0, 's', 'T00', 'li'): (0.158176, 0.000150),
    (450.0, 0.0, 's', 'R_total', 'li'): (0.096806, 0.000042),
    (450.0, 0.0, 's', 'T_total', 'nv'): (0.343384, 0.001407),
    (450.0, 0.0, 's', 'T00', 'nv'): (0.158489, 0.000714),
    (450.0, 0.0, 's', 'R_total', 'nv'): (0.096758, 0.000058),
    (450.0, 30.0, 's', 'T_total', 'li'): (0.280860, 0.000575),
    (450.0, 30.0, 's', 'T00', 'li'): (0.117109, 0.000117),
    (450.0, 30.0, 's', 'R_total', 'li'): (0.092244, 0.000095),
    (450.0, 30.0, 's', 'T_total', 'nv'): (0.281068, 0.000562),
    (450.0, 30.0, 's', 'T00', 'nv'): (0.117247, 0.000939),
    (450.0, 30.0, 's', 'R_total', 'nv'): (0.092243, 0.000035),
    (450.0, 30.0, 'p', 'T_total', 'li'): (0.325769, 0.000183),
    (450.0, 30.0, 'p', 'T00', 'li'): (0.108743, 0.000180),
    (450.0, 30.0, 'p', 'R_total', 'li'): (0.079784, 0.000188),
    (450.0, 30.0, 'p', 'T_total', 'nv'): (0.326513, 0.000909),
    (450.0, 30.0, 'p', 'T00', 'nv'): (0.108960, 0.000335),
    (450.0, 30.0, 'p', 'R_total', 'nv'): (0.079772, 0.000111),
    (550.0, 0.0, 's', 'T_total', 'li'): (0.280727, 0.001387),
    (550.0, 0.0, 's', 'T00', 'li'): (0.075260, 0.006396),
    (550.0, 0.0, 's', 'R_total', 'li'): (0.196126, 0.000428),
    (550.0, 0.0, 's', 'T_total', 'nv'): (0.282172, 0.001906),
    (550.0, 0.0, 's', 'T00', 'nv'): (0.071400, 0.013012),
    (550.0, 0.0, 's', 'R_total', 'nv'): (0.196827, 0.001970),
    (550.0, 30.0, 's', 'T_total', 'li'): (0.372308, 0.001529),
    (550.0, 30.0, 's', 'T00', 'li'): (0.151306, 0.000534),
    (550.0, 30.0, 's', 'R_total', 'li'): (0.174634, 0.000574),
    (550.0, 30.0, 's', 'T_total', 'nv'): (0.371113, 0.000737),
    (550.0, 30.0, 's', 'T00', 'nv'): (0.150353, 0.001256),
    (550.0, 30.0, 's', 'R_total', 'nv'): (0.173856, 0.002875),
    (550.0, 30.0, 'p', 'T_total', 'li'): (0.350158, 0.000799),
    (550.0, 30.0, 'p', 'T00', 'li'): (0.107042, 0.000499),
    (550.0, 30.0, 'p', 'R_total', 'li'): (0.170524, 0.000578),
    (550.0, 30.0, 'p', 'T_total', 'nv'): (0.352693, 0.015516),
    (550.0, 30.0, 'p', 'T00', 'nv'): (0.121897, 0.072347),
    (550.0, 30.0, 'p', 'R_total', 'nv'): (0.170616, 0.001356),
    (650.0, 0.0, 's', 'T_total', 'li'): (0.614281, 0.006852),
    (650.0, 0.0, 's', 'T00', 'li'): (0.023834, 0.002850),
    (650.0, 0.0, 's', 'R_total', 'li'): (0.260203, 0.001937),
    (650.0, 0.0, 's', 'T_total', 'nv'): (0.025376, 3.145150),
    (650.0, 0.0, 's', 'T00', 'nv'): (0.019330, 0.027620),
    (650.0, 0.0, 's', 'R_total', 'nv'): (0.236611, 0.071354),
    (650.0, 30.0, 's', 'T_total', 'li'): (0.435366, 0.000890),
    (650.0, 30.0, 's', 'T00', 'li'): (0.229468, 0.000688),
    (650.0, 30.0, 's', 'R_total', 'li'): (0.446512, 0.005446),
    (650.0, 30.0, 's', 'T_total', 'nv'): (0.154329, 1.167623),
    (650.0, 30.0, 's', 'T00', 'nv'): (0.171316, 0.178368),
    (650.0, 30.0, 's', 'R_total', 'nv'): (0.439493, 0.193113),
    (650.0, 30.0, 'p', 'T_total', 'li'): (0.510067, 0.002748),
    (650.0, 30.0, 'p', 'T00', 'li'): (0.097821, 0.056675),
    (650.0, 30.0, 'p', 'R_total', 'li'): (0.356084, 0.005227),
    (650.0, 30.0, 'p', 'T_total', 'nv'): (0.443841, 0.077782),
    (650.0, 30.0, 'p', 'T00', 'nv'): (0.192527, 0.752134),
    (650.0, 30.0, 'p', 'R_total', 'nv'): (0.472861, 1.534641),
}
# adaptive spatial resolution (rcwa.asr), N = 9..35, as docs/gold2d_convergence.md publishes it
# (`python -m benchmarks.bench_convergence --asr-literal` prints this dict)
PUBLISHED_ASR = {
    (450.0, 0.0, 's', 'T_total', 'asr'): (0.343066, 0.000080),
    (450.0, 0.0, 's', 'T00', 'asr'): (0.158484, 0.000084),
    (450.0, 0.0, 's', 'R_total', 'asr'): (0.096793, 0.000052),
    (450.0, 30.0, 's', 'T_total', 'asr'): (0.280540, 0.000051),
    (450.0, 30.0, 's', 'T00', 'asr'): (0.117037, 0.000029),
    (450.0, 30.0, 's', 'R_total', 'asr'): (0.092201, 0.000031),
    (450.0, 30.0, 'p', 'T_total', 'asr'): (0.325911, 0.000085),
    (450.0, 30.0, 'p', 'T00', 'asr'): (0.108885, 0.000032),
    (450.0, 30.0, 'p', 'R_total', 'asr'): (0.079678, 0.000040),
    (550.0, 0.0, 's', 'T_total', 'asr'): (0.281664, 0.000930),
    (550.0, 0.0, 's', 'T00', 'asr'): (0.076163, 0.000396),
    (550.0, 0.0, 's', 'R_total', 'asr'): (0.195819, 0.000457),
    (550.0, 30.0, 's', 'T_total', 'asr'): (0.371332, 0.000995),
    (550.0, 30.0, 's', 'T00', 'asr'): (0.150299, 0.021007),
    (550.0, 30.0, 's', 'R_total', 'asr'): (0.174770, 0.000123),
    (550.0, 30.0, 'p', 'T_total', 'asr'): (0.350406, 0.000208),
    (550.0, 30.0, 'p', 'T00', 'asr'): (0.107581, 0.000230),
    (550.0, 30.0, 'p', 'R_total', 'asr'): (0.170114, 0.000176),
    (650.0, 0.0, 's', 'T_total', 'asr'): (0.614120, 0.019108),
    (650.0, 0.0, 's', 'T00', 'asr'): (0.024482, 0.000654),
    (650.0, 0.0, 's', 'R_total', 'asr'): (0.261245, 0.001260),
    (650.0, 30.0, 's', 'T_total', 'asr'): (0.431253, 0.001434),
    (650.0, 30.0, 's', 'T00', 'asr'): (0.229154, 0.002232),
    (650.0, 30.0, 's', 'R_total', 'asr'): (0.449246, 0.002809),
    (650.0, 30.0, 'p', 'T_total', 'asr'): (0.506960, 0.005410),
    (650.0, 30.0, 'p', 'T00', 'asr'): (0.090003, 0.001374),
    (650.0, 30.0, 'p', 'R_total', 'asr'): (0.361146, 0.002617),
    (550.0, 0.0, 's', 'T_total', 'asr_nv'): (0.283135, 0.001120),
    (550.0, 0.0, 's', 'T00', 'asr_nv'): (0.075458, 0.002338),
    (550.0, 0.0, 's', 'R_total', 'asr_nv'): (0.195218, 0.001409),
    (650.0, 0.0, 's', 'T_total', 'asr_nv'): (0.594636, 0.021855),
    (650.0, 0.0, 's', 'T00', 'asr_nv'): (0.024539, 0.002862),
    (650.0, 0.0, 's', 'R_total', 'asr_nv'): (0.256175, 0.003719),
}


@pytest.mark.parametrize("wavelength", g2.WAVELENGTHS_NM)
def test_reverse_direction_sends_the_order_back(wavelength):
    b, m_b = g2.reverse_direction(wavelength)
    period = 1.0
    kx_forward = math.sin(math.radians(30.0)) + ORDER_SIGN * 1 * wavelength / 1000.0 / period  # order (1, 0)
    kx_reverse = math.sin(math.radians(b.theta_deg)) + ORDER_SIGN * m_b * wavelength / 1000.0 / period
    # the reverse incidence's order leaves along -k_forward,inc, or its x-mirror image (m_b = -1)
    assert kx_reverse == pytest.approx(-math.sin(math.radians(30.0)) * m_b, abs=1e-12)
    assert math.sin(math.radians(b.theta_deg)) == pytest.approx(abs(kx_forward), abs=1e-12)


@pytest.mark.slow
def test_the_2d_study_writes_its_curve(tmp_path):
    s = rcwa.load_structure("gold2d")
    cfg = CurveConfig(directions=(Direction(550.0, 0.0),), max_orders=23, max_timed_orders=11)
    cache = SolveCache(tmp_path / "raw.json", s)
    data = run_convergence_study(s, tmp_path / "out", cfg, cache, progress=False)
    out = tmp_path / "out"
    rows = list(csv.DictReader(open(out / "accuracy_time.csv")))
    assert len(rows) == 4 * len(cfg.orders()) and {r["rule"] for r in rows} == {"li", "nv", "asr", "asr_nv"}
    assert json.loads((out / "study_rcwa.json").read_text())["rows"] == json.loads(json.dumps(data["rows"]))
    assert (out / "study_rcwa.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    li = {int(r["orders"]): r for r in rows if r["rule"] == "li"}
    assert float(li[23]["error_T_total"]) < float(li[9]["error_T_total"]) / 3
    assert all((r["table_seconds_estimated"] == "True") == (int(r["orders"]) > 11) for r in rows)
    assert all(float(r["seconds_per_table"]) > float(r["seconds_per_solve"]) for r in rows)
    assert len(json.loads(cache.path.read_text())["entries"]) == 4 * (len(cfg.orders()) + 2)  # the curve's and the timing's


@pytest.mark.slow
def test_reciprocity_of_extrapolated_li_values_at_450nm(tmp_path):
    """Order (1, 0) from 30 deg and from its reciprocal incidence, Li's rule, N = 9..23, extrapolated:
    equal within the bars, and the bars small enough to mean something (below RECIPROCITY_BAR = 1e-3,
    a tenth of the smallest efficiency checked; measured <= 3e-4, the differences <= 8e-5)."""
    cache = SolveCache(tmp_path / "raw.json", rcwa.load_structure("gold2d"))
    checks = g2.reciprocity(cache, orders=tuple(range(9, 25, 2)), wavelengths=(450.0,), rules=("li",))
    assert len(checks) == 4  # s and p, R and T
    for c in checks:
        assert c.within_errors, (c.pol, c.side, c.forward.value, c.backward.value)
        assert c.forward.error < RECIPROCITY_BAR and c.backward.error < RECIPROCITY_BAR
        assert c.forward.value > 10 * RECIPROCITY_BAR  # the order carries power


def _published(key):
    if not PUBLISHED:
        pytest.fail("PUBLISHED is empty: copy the table of docs/gold2d_convergence.md into it")
    return PUBLISHED[key]


@pytest.mark.heavy
def test_converged_values_are_the_published_ones():
    values = g2.converged_table(g2.open_cache())
    for v in values:
        value, error = _published((v.wavelength_nm, v.theta_deg, v.pol, v.quantity, v.rule))
        assert v.limit.value == pytest.approx(value, abs=0.1 * error + 1e-6), v.row()
        assert v.limit.error == pytest.approx(error, rel=0.1, abs=1e-6), v.row()


@pytest.mark.heavy
def test_reciprocity_holds_on_the_converged_values():
    checks = g2.reciprocity(g2.open_cache())
    assert all(c.within_errors for c in checks), [(c.wavelength_nm, c.rule, c.pol, c.side) for c in checks
                                                  if not c.within_errors]


def _asr_values(cache):
    """Li's rule in stretched coordinates everywhere, the NV rule's where published (g2.ASR_NV_DIRECTIONS)."""
    return g2.asr_table(cache) + g2.asr_table(cache, rule=g2.ASR_NV_RULE, only=g2.ASR_NV_DIRECTIONS)


@pytest.mark.heavy
def test_adaptive_spatial_resolutions_values_are_the_published_ones():
    """rcwa.asr's converged values (about 30 minutes cold) as docs/gold2d_convergence.md publishes them."""
    for v in _asr_values(g2.open_cache()):
        value, error = PUBLISHED_ASR[(v.wavelength_nm, v.theta_deg, v.pol, v.quantity, v.rule)]
        assert v.limit.value == pytest.approx(value, abs=0.1 * error + 1e-6), v.row()
        assert v.limit.error == pytest.approx(error, rel=0.1, abs=1e-6), v.row()


@pytest.mark.heavy
def test_adaptive_spatial_resolution_agrees_with_li_at_550nm_normal_incidence():
    """Li's rule (published, N <= 61) and ASR (N <= 35) on T_total and T(0,0): within ISSUE_GAP, bars overlapping."""
    for v in g2.asr_table(g2.open_cache()):
        if (v.wavelength_nm, v.theta_deg) == (550.0, 0.0) and v.quantity in ("T_total", "T00"):
            li_value, li_error = PUBLISHED[(550.0, 0.0, "s", v.quantity, "li")]
            assert abs(v.limit.value - li_value) <= min(ISSUE_GAP, v.limit.error + li_error), v.row()


@pytest.mark.heavy
def test_both_rules_agree_in_stretched_coordinates_at_550nm_normal_incidence():
    """The issue's bar with both rules in adaptive spatial resolution's coordinates: Li's and the NV
    rule's T_total and T(0,0) within ISSUE_GAP, the bars overlapping."""
    cache = g2.open_cache()
    only = (Direction(550.0, 0.0),)
    li = {v.quantity: v.limit for v in g2.asr_table(cache, only=only)}
    nv = {v.quantity: v.limit for v in g2.asr_table(cache, rule=g2.ASR_NV_RULE, only=only)}
    for quantity in ("T_total", "T00"):
        gap = abs(li[quantity].value - nv[quantity].value)
        assert gap <= ISSUE_GAP and gap <= li[quantity].error + nv[quantity].error, (quantity, li[quantity], nv[quantity])


@pytest.mark.heavy
def test_reciprocity_holds_on_adaptive_spatial_resolutions_values():
    checks = g2.reciprocity(g2.open_cache(), orders=g2.ASR_ORDERS, rules=(g2.ASR_RULE,))
    assert all(c.within_errors for c in checks), [(c.wavelength_nm, c.pol, c.side) for c in checks if not c.within_errors]


def _at_550_normal(values, quantity):
    pick = {v.rule: v.limit for v in values if (v.wavelength_nm, v.theta_deg, v.quantity) == (550.0, 0.0, quantity)}
    return pick["li"], pick["nv"]


@pytest.mark.heavy
def test_the_rules_agree_on_T_total_at_550nm_normal_incidence():
    """The issue's bar: both rules' extrapolated T_total within ISSUE_GAP = 0.003, the bars overlapping."""
    li, nv = _at_550_normal(g2.converged_table(g2.open_cache()), "T_total")
    assert abs(li.value - nv.value) <= ISSUE_GAP
    assert abs(li.value - nv.value) <= li.error + nv.error


@pytest.mark.heavy
@pytest.mark.xfail(strict=True, reason="measured at N <= 61: li 0.0753 +- 0.0064, nv 0.0714 +- 0.0130, 0.0039 apart "
                                       "(the bars overlap, the issue's 0.003 is not reached; docs/gold2d_convergence.md)")
def test_the_rules_agree_on_T00_at_550nm_normal_incidence():
    li, nv = _at_550_normal(g2.converged_table(g2.open_cache()), "T00")
    assert abs(li.value - nv.value) <= ISSUE_GAP and abs(li.value - nv.value) <= li.error + nv.error

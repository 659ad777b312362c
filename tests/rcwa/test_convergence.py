"""Li's inverse rule against the Laurent rule for a metallic lamellar grating in TM.

Li 1996 (JOSA A 13, 1870) shows the inverse rule converging far faster for TM metal
gratings. Asserted: the number of harmonics the Laurent rule needs to come (and stay)
within 1e-2 of the converged Littrow efficiency is at least MIN_RATIO times what the
inverse rule needs. Measured here: 21 against 161 (ratio 7.7); MIN_RATIO = 4 leaves
room for a different reference while still failing if the rules were swapped or equal.
`python -m benchmarks.bench_convergence` (make bench) prints the whole curve.
"""

from rcwa.convergence import lamellar_tm_study, orders_to_reach

MIN_RATIO = 4
TARGET_ERROR = 1e-2
ORDERS = (11, 21, 41, 81, 161)
REFERENCE_ORDERS = 401


def test_inverse_rule_converges_faster_than_laurent():
    points = lamellar_tm_study(orders=ORDERS, reference_orders=REFERENCE_ORDERS)
    li = orders_to_reach(points, "li", TARGET_ERROR)
    laurent = orders_to_reach(points, "laurent", TARGET_ERROR)
    assert li is not None
    laurent = laurent if laurent is not None else 2 * ORDERS[-1]
    assert laurent / li >= MIN_RATIO, (li, laurent)

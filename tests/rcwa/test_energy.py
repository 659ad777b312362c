"""Energy conservation R + T = 1 for lossless structures, over random structures and angles.

Tolerance 1e-9: every factorization rule gives a Hermitian truncated permittivity for
lossless media, so the truncated problem itself conserves energy exactly and only
round-off (about 1e-13 here) remains.
"""

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import rcwa
from tests.rcwa.helpers import nk, structure

TOLERANCE_ENERGY = 1e-9

index = st.floats(1.0, 3.2)
angles = st.tuples(st.floats(0.0, 85.0), st.floats(0.0, 360.0))


@st.composite
def lamellar_layers(draw):
    period = draw(st.floats(0.3, 2.0))
    layers = []
    for _ in range(draw(st.integers(1, 3))):
        shapes = []
        for _ in range(draw(st.integers(0, 3))):
            x0 = draw(st.floats(0.0, period))
            width = draw(st.floats(0.02, 1.0)) * period
            shapes.append({"material": nk(draw(index)), "x": [x0, x0 + width]})
        layers.append({"thickness": draw(st.floats(0.0, 1.0)), "material": nk(draw(index)), "shapes": shapes})
    return period, layers


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lamellar_layers(), index, index, angles, st.floats(400, 800), st.sampled_from([11, 21, 31]),
       st.sampled_from(["s", "p"]), st.sampled_from(["li", "laurent"]), st.sampled_from(["etm", "smatrix"]))
def test_lossless_1d_conserves_energy(cell, n_sup, n_sub, angle, wavelength, orders, pol, rule, stack):
    period, layers = cell
    s = structure([period], nk(n_sup), nk(n_sub), layers)
    result = rcwa.solve(s, wavelength, angle[0], angle[1], orders, pol, rule, stack)
    assert abs(result.R_total + result.T_total - 1.0) < TOLERANCE_ENERGY
    assert abs(result.absorption) < TOLERANCE_ENERGY


def test_layer_painted_back_to_its_background_in_conical_incidence():
    """Found by hypothesis: round-off on the eigenvalues of a contrast-free patterned layer
    flipped propagating modes to Re(kz) < 0 and broke the ETM stack (R + T = 1.18)."""
    period = 0.9329896538126565
    shapes = [{"material": nk(2.0), "x": [0.0, period]}, {"material": nk(1.0), "x": [0.0, period]}]
    for thickness in (0.0, 0.1):
        s = structure([period], nk(1.0), nk(1.0), [{"thickness": thickness, "material": nk(1.0), "shapes": shapes}])
        for stack in ("etm", "smatrix"):
            r = rcwa.solve(s, 400.0, 1.0, 1.921875, 11, "s", "li", stack)
            assert abs(r.R_total + r.T_total - 1.0) < TOLERANCE_ENERGY
            assert r.T_total > 1.0 - TOLERANCE_ENERGY  # it is just air


@st.composite
def crossed_layer(draw):
    lx, ly = draw(st.floats(0.4, 1.5)), draw(st.floats(0.4, 1.5))
    shapes = []
    for _ in range(draw(st.integers(1, 2))):
        cx, cy = draw(st.floats(0, lx)), draw(st.floats(0, ly))
        kind = draw(st.sampled_from(["rect", "circle", "polygon"]))
        if kind == "rect":
            geometry = {"center": [cx, cy], "size": [draw(st.floats(0.05, 0.9)) * lx, draw(st.floats(0.05, 0.9)) * ly]}
        elif kind == "circle":
            geometry = {"center": [cx, cy], "radius": draw(st.floats(0.05, 0.45)) * min(lx, ly)}
        else:
            r = 0.3 * min(lx, ly)
            geometry = [[cx, cy], [cx + r, cy], [cx + 0.3 * r, cy + r]]
        shapes.append({"material": nk(draw(index)), kind: geometry})
    return (lx, ly), [{"thickness": draw(st.floats(0.05, 0.6)), "material": nk(draw(index)), "shapes": shapes}]


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(crossed_layer(), index, index, angles, st.floats(400, 800), st.sampled_from(["s", "p"]),
       st.sampled_from(["li", "nv", "laurent"]))
def test_lossless_2d_conserves_energy(cell, n_sup, n_sub, angle, wavelength, pol, rule):
    period, layers = cell
    s = structure(period, nk(n_sup), nk(n_sub), layers)
    result = rcwa.solve(s, wavelength, angle[0], angle[1], (5, 5), pol, rule)
    assert abs(result.R_total + result.T_total - 1.0) < TOLERANCE_ENERGY

"""Per-order Jones and Mueller matrices (rcwa.polarimetry; issue 47, item 1).

Analytic checks: the Mueller matrix's first row is the unpolarized efficiency and half the
s-p difference of the solver's own efficiencies (to 1e-10: the same numbers, combined
another way); a lossless grating's orders' M00 sum to 1 (energy; to 1e-9, RCWA conserves
energy for lossless media to round-off at any truncation); a flat air/N-BK7 interface
(a grating whose one layer is the substrate's glass) gives Fresnel's coefficients, signs
included [Born 1999, Sec. 1.5.2], and at Brewster's angle its reflected p part vanishes (1e-8);
s and p do not mix in the classical mount of a 1D grating and do in the conical mount;
every matrix derived from a Jones matrix passes Cloude's realisability test, and a
non-physical one fails it."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import rcwa
from rcwa.polarimetry import coherency_eigenvalues, jones_matrices, mueller_from_jones
from rcwa.structure import Structure
from workbench.cli import main

SILICA_GRATING = """
name = "silica_grating"
period = [0.8]
superstrate = "air"
substrate = "fused_silica"

[[layers]]
thickness = 0.2
material = "air"
shapes = [ { material = "fused_silica", x = [0.0, 0.4] } ]
"""
FLAT_GLASS = """
name = "flat_glass"
period = [0.5]
superstrate = "air"
substrate = "n-bk7"

[[layers]]
thickness = 0.1
material = "n-bk7"
"""


def _structure(text: str) -> Structure:
    return Structure.from_toml_string(text, source="test.toml")


@pytest.mark.parametrize("name, text, theta, phi", [
    ("cd", None, 25.0, 35.0), ("silica, conical", SILICA_GRATING, 30.0, 40.0), ("silica, classical", SILICA_GRATING, 20.0, 0.0),
])
def test_the_first_row_is_the_solvers_efficiencies(name, text, theta, phi):
    structure = rcwa.load_structure("cd") if text is None else _structure(text)
    result = rcwa.solve(structure, 550.0, theta, phi, 31)
    checked = 0
    for order in result.orders:
        for side, jones in jones_matrices(order).items():
            if jones is None:
                continue
            m = mueller_from_jones(jones)
            s, p = (order.R_s, order.R_p) if side == "R" else (order.T_s, order.T_p)
            assert m[0, 0] == pytest.approx((s + p) / 2, abs=1e-10)
            assert m[0, 1] == pytest.approx((s - p) / 2, abs=1e-10)
            assert min(coherency_eigenvalues(m)) > -1e-12
            checked += 1
    assert checked >= 4


def test_a_lossless_gratings_orders_carry_all_the_power():
    result = rcwa.solve(_structure(SILICA_GRATING), 500.0, 35.0, 25.0, 31)
    total = sum(mueller_from_jones(j)[0, 0] for o in result.orders for j in jones_matrices(o).values() if j is not None)
    assert total == pytest.approx(1.0, abs=1e-9)


def test_s_and_p_mix_only_off_the_classical_mount():
    cd = rcwa.load_structure("cd")
    classical = rcwa.solve(cd, 550.0, 20.0, 0.0, 31).order(-1)
    conical = rcwa.solve(cd, 550.0, 20.0, 35.0, 31).order(-1)
    j0, j1 = jones_matrices(classical)["R"], jones_matrices(conical)["R"]
    assert abs(j0[0, 1]) < 1e-12 and abs(j0[1, 0]) < 1e-12
    assert abs(j1[0, 1]) > 1e-3 and abs(j1[1, 0]) > 1e-3


@pytest.mark.parametrize("theta", [10.0, 45.0, 70.0])
def test_a_flat_interface_gives_fresnels_coefficients(theta):
    structure = _structure(FLAT_GLASS)
    n = float(np.real(structure.substrate.refractive_index(np.array([550.0]))[0]))
    ci = math.cos(math.radians(theta))
    ct = math.sqrt(1 - (math.sin(math.radians(theta)) / n) ** 2)
    rs, rp = (ci - n * ct) / (ci + n * ct), (n * ci - ct) / (n * ci + ct)  # [Born 1999] (1.5.20a), (1.5.21a)
    order = rcwa.solve(structure, 550.0, theta, 0.0, 11).order(0)
    jr, jt = jones_matrices(order)["R"], jones_matrices(order)["T"]
    # amplitudes, signs included: the basis (s-hat, k-hat x s-hat) gives Born & Wolf's signs (r_p = -r_s at 0 deg)
    assert jr[0, 0] == pytest.approx(rs, abs=1e-9) and jr[1, 1] == pytest.approx(rp, abs=1e-9)
    assert abs(jt[0, 0]) ** 2 == pytest.approx(1 - rs**2, abs=1e-10)
    assert abs(jt[1, 1]) ** 2 == pytest.approx(1 - rp**2, abs=1e-10)


def test_at_brewsters_angle_the_reflected_p_part_vanishes():
    structure = _structure(FLAT_GLASS)
    n = float(np.real(structure.substrate.refractive_index(np.array([550.0]))[0]))
    order = rcwa.solve(structure, 550.0, math.degrees(math.atan(n)), 0.0, 11).order(0)
    m = mueller_from_jones(jones_matrices(order)["R"])
    rs2 = 2 * m[0, 0]
    assert abs(jones_matrices(order)["R"][1, 1]) < 1e-8
    np.testing.assert_allclose(m, rs2 / 2 * np.array([[1, 1, 0, 0], [1, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]]),
                               atol=1e-8)


def test_a_non_physical_matrix_fails_the_realisability_test():
    assert min(coherency_eigenvalues(np.diag([1.0, 1.5, 0.0, 0.0]))) < -0.1


def test_rcwa_solve_json_prints_each_orders_jones_and_mueller(capsys):
    assert main(["rcwa", "solve", "cd", "--wavelength", "550", "--theta", "20", "--orders", "41", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert "p-hat = k-hat x s-hat" in record["polarimetry"]
    minus_one = next(o for o in record["orders"] if o["m"] == -1)
    # the numbers: the -1 order reflects 0.327 of s and 0.248 of p light
    assert minus_one["mueller_R"][0][0] == pytest.approx((0.327 + 0.248) / 2, abs=1e-3)
    assert minus_one["mueller_R"][0][1] == pytest.approx((0.327 - 0.248) / 2, abs=1e-3)
    assert minus_one["jones_T"] is None and minus_one["mueller_T"] is None  # an aluminium substrate
    assert len(minus_one["jones_R"]) == 2 and len(minus_one["jones_R"][0][0]) == 2

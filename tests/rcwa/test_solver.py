"""rcwa/solver.py: request validation, the fields of a result, polarization averaging and
the bookkeeping from amplitudes to efficiencies.

The physics of the solve itself is tested elsewhere (test_thin_film.py: Airy/Fresnel
limits; test_energy.py, test_reciprocity.py, test_invariance.py, test_published.py,
test_peer.py). Here: what a caller sees.

Tolerances: TOLERANCE_BOOKKEEPING = 1e-12 for identities between fields of one result
(sums, means, |amplitude|^2 times flux factors): the same floating-point numbers combined
in a different order; TOLERANCE_FLUX = 1e-12 for power continuity across a bare
interface (R + power into the substrate = 1: exact in the solve, round-off only).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import rcwa
from tests.rcwa.helpers import lamellar, nk, structure
from workbench.core.errors import UserInputError

TOLERANCE_BOOKKEEPING = 1e-12
TOLERANCE_FLUX = 1e-12

GRATING = lamellar(period=1.2, depth=0.35, n_ridge=nk(2.0, 0.05), fill=(0.1, 0.5))  # lossy, asymmetric
CROSSED = structure([1.0, 0.8], nk(1.0), nk(1.5), [{"thickness": 0.2, "material": nk(1.0),
                    "shapes": [{"material": nk(2.0), "circle": {"center": [0.4, 0.4], "radius": 0.25}}]}])
REQUEST = {"wavelength_nm": 550.0, "theta_deg": 25.0, "phi_deg": 40.0, "orders": 21, "pol": "s"}

# ---------------------------------------------------------------- validation

BAD_REQUESTS = {
    "even orders": ({"orders": 10}, "orders"),
    "no orders": ({"orders": 0}, "orders"),
    "negative orders": ({"orders": -3}, "orders"),
    "orders given as True": ({"orders": True}, "orders"),
    "two order counts for 1D": ({"orders": (11, 11)}, "orders"),
    "negative theta": ({"theta_deg": -1.0}, "theta"),
    "theta not a number": ({"theta_deg": float("nan")}, "theta"),
    "theta of 90 deg": ({"theta_deg": 90.0}, "theta"),
    "infinite phi": ({"phi_deg": float("inf")}, "phi"),
    "zero wavelength": ({"wavelength_nm": 0.0}, "wavelength"),
    "wavelength not a number": ({"wavelength_nm": float("nan")}, "wavelength"),
    "wavelength as a word": ({"wavelength_nm": "green"}, "wavelength"),
    "polarization TE": ({"pol": "TE"}, "pol"),
    "unknown factorization": ({"factorization": "lii"}, "factorization"),
    "unknown stack": ({"stack": "tmm"}, "stack"),
    "orders as a float": ({"orders": 11.0}, "orders"),
    "theta as a string": ({"theta_deg": "10"}, "theta"),
    "orders beyond memory (1D)": ({"orders": 100001}, "orders"),
}


def _request_error(change: dict) -> UserInputError:
    with pytest.raises(UserInputError) as info:
        rcwa.solve(GRATING, **{**REQUEST, **change})
    return info.value


@pytest.mark.parametrize("case", BAD_REQUESTS)
def test_bad_request_is_a_user_error_naming_its_field(case):
    change, field = BAD_REQUESTS[case]
    error = _request_error(change)
    assert error.field == field and f"field '{field}'" in str(error)


@pytest.mark.parametrize("orders", [(5,), (5, 4), 6, (5, 5, 5)])
def test_2d_order_counts(orders):
    with pytest.raises(UserInputError) as info:
        rcwa.solve(CROSSED, 550.0, 10.0, 0.0, orders, "s")
    assert info.value.field == "orders" and info.value.expected


def test_an_int_means_the_same_count_in_x_and_y():
    a, b = rcwa.solve(CROSSED, 550.0, 10.0, 30.0, 5, "p"), rcwa.solve(CROSSED, 550.0, 10.0, 30.0, (5, 5), "p")
    assert a.orders_retained == b.orders_retained == (5, 5)
    assert np.array_equal(a.all_orders["R"], b.all_orders["R"])


def test_lossy_superstrate_is_refused_naming_file_and_field():
    s = structure([1.0], nk(1.5, 0.1), nk(1.5), [])
    with pytest.raises(UserInputError) as info:
        rcwa.solve(s, 550.0, 0.0, 0.0, 3, "s")
    assert info.value.field == "superstrate" and info.value.file == s.source and "lossless" in str(info.value)


# ---------------------------------------------------------------- result fields


def test_result_describes_its_request():
    r = rcwa.solve(GRATING, **REQUEST)
    assert (r.structure, r.wavelength_nm, r.theta_deg, r.phi_deg, r.pol) == (GRATING.name, 550.0, 25.0, 40.0, "s")
    assert r.orders_retained == (21,) and r.factorization == "li"  # "auto" is resolved
    k = 21
    assert all(r.all_orders[key].shape == (k,) for key in ("m", "n", "kz_superstrate", "kz_substrate"))
    assert all(r.all_orders[key].shape == (k, 2) for key in ("R", "T", "T_into_substrate"))
    assert list(r.all_orders["m"]) == list(range(-10, 11)) and not r.all_orders["n"].any()


def test_orders_are_the_propagating_ones():
    r = rcwa.solve(GRATING, **REQUEST)
    kz_sup, kz_sub = r.all_orders["kz_superstrate"], r.all_orders["kz_substrate"]
    propagating = {int(m) for m, a, b in zip(r.all_orders["m"], kz_sup, kz_sub, strict=True) if a.real > 0 or b.real > 0}
    assert {o.m for o in r.orders} == propagating and len(propagating) >= 3
    for o in r.orders:
        assert o.propagating_R == (o.direction_R is not None) and o.propagating_T == (o.direction_T is not None)
        assert o.propagating_R or o.R == 0.0  # an order evanescent on one side carries nothing there
        assert o.propagating_T or o.T == 0.0
    evanescent = next(int(m) for m in r.all_orders["m"] if int(m) not in propagating)
    with pytest.raises(KeyError):
        r.order(evanescent)
    with pytest.raises(KeyError):
        r.order(99)  # not retained


def test_orders_are_built_once_on_first_use_from_the_solve_arrays():
    """SolveResult.orders is built on first access (order_builder) and kept: the same list
    object afterwards, and each order's efficiencies are the all_orders row of its harmonic
    (the same numbers, so equal to the bookkeeping tolerance)."""
    r = rcwa.solve(GRATING, **REQUEST)
    assert "orders" not in r.__dict__  # nothing built by the solve itself
    first = r.orders
    assert r.orders is first
    m = list(r.all_orders["m"])
    for o in first:
        i = m.index(o.m)
        assert o.R_s == pytest.approx(r.all_orders["R"][i, 0], abs=TOLERANCE_BOOKKEEPING)
        assert o.T_s == pytest.approx(r.all_orders["T"][i, 0], abs=TOLERANCE_BOOKKEEPING)


def test_totals_and_absorption():
    r = rcwa.solve(GRATING, **REQUEST)
    assert r.R_total == pytest.approx(sum(o.R for o in r.orders), abs=TOLERANCE_BOOKKEEPING)
    assert r.T_total == pytest.approx(sum(o.T for o in r.orders), abs=TOLERANCE_BOOKKEEPING)
    assert r.absorption == pytest.approx(1.0 - r.R_total - r.T_total, abs=TOLERANCE_BOOKKEEPING)
    assert r.absorption > 1e-3  # the ridge absorbs: the identity is not 0 = 0


def test_to_dict_is_json_with_the_documented_fields():
    r = rcwa.solve(GRATING, **REQUEST)
    data = json.loads(json.dumps(r.to_dict()))
    assert {"structure", "wavelength_nm", "theta_deg", "phi_deg", "pol", "orders_retained", "factorization",
            "R_total", "T_total", "absorption", "orders"} <= set(data)
    assert [(o["m"], o["n"], o["R"], o["T"]) for o in data["orders"]] == [(o.m, o.n, o.R, o.T) for o in r.orders]


# ---------------------------------------------------------------- polarization


@pytest.mark.parametrize("s, orders", [(GRATING, 21), (CROSSED, (5, 5))], ids=["1D conical", "2D"])
def test_unpolarized_is_the_mean_of_s_and_p(s, orders):
    by_pol = {pol: rcwa.solve(s, 550.0, 25.0, 40.0, orders, pol) for pol in ("s", "p", "unpolarized")}
    for pol in ("s", "p"):  # s and p efficiencies do not depend on which one was asked for
        assert np.array_equal(by_pol[pol].all_orders["R"], by_pol["unpolarized"].all_orders["R"])
    mean = 0.5 * (by_pol["s"].R_total + by_pol["p"].R_total)
    assert by_pol["unpolarized"].R_total == pytest.approx(mean, abs=TOLERANCE_BOOKKEEPING)
    assert abs(by_pol["s"].R_total - by_pol["p"].R_total) > 1e-3  # s and p really differ here
    for o in by_pol["unpolarized"].orders:
        assert o.R == pytest.approx(o.R_unpolarized, abs=TOLERANCE_BOOKKEEPING)
        assert o.T == pytest.approx(0.5 * (o.T_s + o.T_p), abs=TOLERANCE_BOOKKEEPING)
    for o in by_pol["s"].orders:
        assert (o.R, o.T) == (o.R_s, o.T_s)


def test_efficiencies_are_the_fluxes_of_the_amplitudes():
    """The core's efficiencies (rcwa/cpp/efficiency.hpp): an s wave (E along s-hat) carries |a|^2 Re(kz), a p wave
    (h = Z0 H along s-hat) |b|^2 Re(kz / eps), through z = const; the incident s wave kz0."""
    s = lamellar(period=1.2, depth=0.35, n_ridge=nk(2.0, 0.05), sup=nk(1.3), sub=nk(1.5))
    r = rcwa.solve(s, 550.0, 25.0, 40.0, 21, "s")
    eps_sup, eps_sub = 1.3**2, 1.5**2
    index = {int(m): i for i, m in enumerate(r.all_orders["m"])}
    kz0 = math.cos(math.radians(25.0)) * 1.3
    for o in r.orders:
        a = o.amplitudes
        kz_r, kz_t = r.all_orders["kz_superstrate"][index[o.m]], r.all_orders["kz_substrate"][index[o.m]]
        R_s = (abs(a["r_s_from_s"]) ** 2 * kz_r.real + abs(a["r_p_from_s"]) ** 2 * (kz_r / eps_sup).real) / kz0
        T_p = (abs(a["t_s_from_p"]) ** 2 * kz_t.real + abs(a["t_p_from_p"]) ** 2 * (kz_t / eps_sub).real) / (kz0 / eps_sup)
        assert o.R_s == pytest.approx(R_s, abs=TOLERANCE_BOOKKEEPING)
        assert o.T_p == pytest.approx(T_p, abs=TOLERANCE_BOOKKEEPING)


def test_nothing_is_transmitted_into_an_absorbing_substrate_but_power_enters_it():
    """Over a metal half-space T (power reaching infinity) is zero; the power crossing the
    interface, ``T_into_substrate``, is what reflection leaves: 1 - R (a bare interface
    under a lossless superstrate has nowhere else to lose it)."""
    s = structure([1.0], nk(1.0), nk(0.5, 3.0), [])
    for pol in ("s", "p"):
        r = rcwa.solve(s, 550.0, 35.0, 10.0, 3, pol)
        column = "sp".index(pol)
        assert r.T_total == 0.0 and not r.all_orders["T"].any()
        into = float(r.all_orders["T_into_substrate"][:, column].sum())
        assert into > 0.05 and r.R_total + into == pytest.approx(1.0, abs=TOLERANCE_FLUX)
        assert r.absorption == pytest.approx(into, abs=TOLERANCE_FLUX)


def test_a_truncation_beyond_memory_says_how_much_it_needs():
    """Refused before any allocation (a 100001-harmonic solve would ask numpy for 75 GiB)."""
    error = _request_error({"orders": 100001})
    assert "GiB" in error.reason and "harmonics" in (error.expected or "")

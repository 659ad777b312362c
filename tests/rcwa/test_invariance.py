"""Equivalent unit cells give the same answer: a 1D grating as a y-invariant 2D cell.

A 1D grating (period [Lx], stripes) and the 2D cell of period [Lx, Ly] whose rectangles
span the whole y period are the same physical structure. With Ny = 1 retained y
harmonics the 2D solve has the same harmonics, the same Fourier coefficients and, for the
rules checked (Li 1997 reduces to Li 1996 when no y-slab differs from another; Laurent is
Laurent), the same permittivity matrices as the 1D solve: only the eigen path differs (two
N x N eigen-solves of the lamellar path against one 2N x 2N solve of the general path,
docs/architecture.md). With Ny = 3 the extra y harmonics couple to nothing (every
coefficient c(g, h != 0) of a y-invariant cell vanishes), so they carry no power and the
n = 0 orders are unchanged. A third equivalent cell: the same grating turned by 90 degrees
about z (varying along y, x-invariant, Nx = 1) with the incidence turned with it
(phi -> phi + 90 deg); rotations keep s and p and map order m of the 1D grating to n.

Tolerances, each with its reason:
* TOLERANCE_INVARIANCE = 1e-11 on every order's efficiency (s and p incidence) and on
  every complex amplitude: the same truncated problem solved by two eigen paths, so only
  their round-off separates them. Measured on the CD (aluminium, 41-61 harmonics, normal,
  classical and conical incidence, Ly = 0.3 and 2 um): <= 1.1e-13.
* TOLERANCE_DECOUPLED = 1e-20 on the power of each n != 0 order: their coupling
  coefficients are sin(pi n) evaluated in floating point (~1e-16), so their amplitudes are
  ~1e-15 and their powers ~1e-30 (measured <= 6e-28); any real coupling would put
  >= 1e-6 there.
"""

from __future__ import annotations

import tomllib
from importlib import resources

import numpy as np
import pytest

import rcwa
from tests.rcwa.helpers import nk

TOLERANCE_INVARIANCE = 1e-11
TOLERANCE_DECOUPLED = 1e-20
HARMONICS = 31
WAVELENGTH_NM = 480.0

INCIDENCE = {"normal": (0.0, 0.0), "classical": (30.0, 0.0), "conical": (45.0, 60.0), "conical, phi > 180": (70.0, 200.0)}


def _cd_dict() -> dict:
    """The built-in CD structure file, as data (rcwa/structures/cd.toml)."""
    return tomllib.loads(resources.files("rcwa.structures").joinpath("cd.toml").read_text())


def _lamellar_dict() -> dict:
    """A lossless dielectric lamellar grating whose ridge wraps across the cell edge."""
    return {"period": [1.0], "superstrate": nk(1.0), "substrate": nk(1.5),
            "layers": [{"thickness": 0.5, "material": nk(1.0), "shapes": [{"material": nk(2.0), "x": [0.8, 1.25]}]},
                       {"thickness": 0.1, "material": nk(1.7)}]}


STRUCTURES = {"cd": _cd_dict, "lamellar dielectric": _lamellar_dict}


def y_invariant_cell(data: dict, ly: float, axis: int = 0) -> dict:
    """The same structure as a 2D cell: each stripe [x0, x1] becomes a rectangle spanning
    the whole other period. ``axis = 1`` turns the grating by 90 deg about z (x -> y)."""
    lx = data["period"][0]

    def rect(stripe: dict) -> dict:
        x0, x1 = stripe["x"]
        centre, size = [(x0 + x1) / 2 % lx, ly / 2], [x1 - x0, ly]
        if axis == 1:
            centre, size = centre[::-1], size[::-1]
        return {"material": stripe["material"], "rect": {"center": centre, "size": size}}

    layers = [{**layer, "shapes": [rect(s) for s in layer.get("shapes", [])]} for layer in data["layers"]]
    period = [lx, ly] if axis == 0 else [ly, lx]
    return {**data, "name": f"{data.get('name', 'grating')} as 2D", "period": period, "layers": layers}


def _solve(data: dict, theta: float, phi: float, orders, rule: str):
    # "unpolarized": both incident states are solved (a 1D classical-mount "s" solve leaves p unsolved).
    return rcwa.solve(rcwa.Structure.from_dict(data), WAVELENGTH_NM, theta, phi, orders, "unpolarized", rule)


def assert_same_orders(one_d, two_d, two_d_index) -> None:
    """Efficiencies (s and p incidence) and amplitudes of every 1D order m equal those of
    the 2D order two_d_index(m); every other 2D order carries no power."""
    m2, n2 = two_d.all_orders["m"], two_d.all_orders["n"]
    position = {(int(a), int(b)): i for i, (a, b) in enumerate(zip(m2, n2, strict=True))}
    matched = [position[two_d_index(int(m))] for m in one_d.all_orders["m"]]
    for key in ("R", "T_into_substrate"):
        np.testing.assert_allclose(two_d.all_orders[key][matched], one_d.all_orders[key], rtol=0, atol=TOLERANCE_INVARIANCE)
    for order in one_d.orders:
        twin = two_d.order(*two_d_index(order.m))
        for name, value in order.amplitudes.items():
            assert abs(twin.amplitudes[name] - value) < TOLERANCE_INVARIANCE, (order.m, name)
    others = np.setdiff1d(np.arange(m2.size), matched)
    for key in ("R", "T_into_substrate"):
        assert np.all(two_d.all_orders[key][others] < TOLERANCE_DECOUPLED)


@pytest.mark.parametrize("incidence", INCIDENCE)
@pytest.mark.parametrize("name", STRUCTURES)
@pytest.mark.parametrize("rule", ["li", "laurent"])
@pytest.mark.parametrize("ny, ly", [(1, 0.3), (3, 2.0)], ids=["Ny=1", "Ny=3, y orders propagate"])
def test_one_d_grating_equals_y_invariant_cell(name, incidence, rule, ny, ly):
    data = STRUCTURES[name]()
    theta, phi = INCIDENCE[incidence]
    one_d = _solve(data, theta, phi, HARMONICS, rule)
    two_d = _solve(y_invariant_cell(data, ly), theta, phi, (HARMONICS, ny), rule)
    assert two_d.factorization == one_d.factorization == rule
    assert_same_orders(one_d, two_d, lambda m: (m, 0))
    if ny == 3:
        # With Ly = 2 um the n = +-1 orders propagate in the superstrate: the test asks a
        # real question of them (they could carry power), not only of evanescent ones.
        propagating = two_d.all_orders["kz_superstrate"].real > 0
        assert np.any(propagating & (two_d.all_orders["n"] != 0))


@pytest.mark.parametrize("incidence", ["classical", "conical"])
@pytest.mark.parametrize("name", STRUCTURES)
def test_grating_turned_by_90_degrees_with_its_incidence(name, incidence):
    """Rotation by +90 deg about z maps (kx, ky) to (-ky, kx): the grating vector x to y,
    azimuth phi to phi + 90, order m of the 1D grating to (0, m) of the turned cell."""
    data = STRUCTURES[name]()
    theta, phi = INCIDENCE[incidence]
    one_d = _solve(data, theta, phi, HARMONICS, "li")
    turned = _solve(y_invariant_cell(data, 0.7, axis=1), theta, phi + 90.0, (1, HARMONICS), "li")
    assert_same_orders(one_d, turned, lambda m: (0, m))


def test_normal_vector_method_on_a_y_invariant_cell_is_li():
    """In a y-invariant cell every boundary is normal to x, n = x-hat everywhere, and
    Schuster et al. 2007's Exx = E - Delta [[nx nx]] is Li's inverse rule exactly."""
    data = _cd_dict()
    one_d = _solve(data, 30.0, 35.0, 21, "li")
    two_d = _solve(y_invariant_cell(data, 0.7), 30.0, 35.0, (21, 1), "nv")
    assert_same_orders(one_d, two_d, lambda m: (m, 0))

"""The core's fast paths give the general path's answer.

In a 1D stack at k_y = 0 (classical mount) TE and TM decouple in every layer and at both
half-spaces; the core then solves each polarization on N x N blocks, and only the one
asked for (rcwa/cpp/polarized.hpp). Lossless 1D layers are solved with Hermitian
eigen-solvers, in classical and conical mounts (rcwa/cpp/modes.hpp, LamellarParts), in real
arithmetic where the layer is symmetric about a point (rcwa/cpp/linalg.hpp, real_by_phase). In
exact arithmetic both are the general path's computation (with its zero blocks left out,
or with other eigenvector normalizations), so they must agree to round-off: 1e-12 (the
issue's bound; measured <= 8e-15 on these cases), on efficiencies and on every complex
amplitude of every retained harmonic, including at a Rayleigh point, at normal incidence,
over a metal, and for a lossless layer next to a lossy one.
"""

import math

import numpy as np
import pytest

import rcwa
from rcwa import _core
from rcwa.solver import INCIDENCE_OF, prepare, s_direction
from rcwa.solver import STACK_METHODS as STACK_METHOD_OF
from tests.rcwa.helpers import lamellar, nk, structure
from workbench.core.conventions import incident_tangential_k

TOLERANCE_FAST = 1e-12  # fast path vs general path (round-off only: same algebra, fewer zeros)

# P2: the dielectric binary grating of Moharam, Grann, Pommet & Gaylord 1995 (JOSA A 12,
# 1068, Fig. 2: period 10 lambda, n = 2.04, fill 0.3, 10 deg), one wavelength deep.
P2 = structure([10.0], nk(1.0), nk(2.04), [
    {"thickness": 1.0, "material": nk(1.0), "shapes": [{"material": nk(2.04), "x": [0.0, 3.0]}]}])
MIXED = structure([1.0], nk(1.0), nk(1.5), [
    {"thickness": 0.3, "material": nk(1.0), "shapes": [{"material": nk(2.0), "x": [0.1, 0.4]}]},   # lossless
    {"thickness": 0.2, "material": nk(1.6, 0.05), "shapes": [{"material": nk(1.0, 0.05), "x": [0, 0.5]}]},  # lossy
    {"thickness": 0.1, "material": nk(2.0)},  # uniform
    {"thickness": 0.05, "material": nk(1.0), "shapes": [{"material": nk(0.2, 3.4), "x": [0.2, 0.7]}]}])  # metal

# A lossless layer symmetric about no point (two different stripes): its matrices cannot be
# made real by moving the origin, so its Hermitian solves stay complex (zheevd / zhegvd),
# while P2's and MIXED's first layer (one stripe) are solved in real arithmetic.
ASYMMETRIC = structure([1.0], nk(1.0), nk(1.5), [
    {"thickness": 0.3, "material": nk(1.0), "shapes": [{"material": nk(2.0), "x": [0.1, 0.3]},
                                                       {"material": nk(1.5), "x": [0.45, 0.9]}]}])

# Order -2 of a 1 um grating at 600 nm grazes the air superstrate where sin(theta) = 0.2.
RAYLEIGH_THETA = math.degrees(math.asin(0.2))

CASES = {
    "P2 oblique": (P2, 1000.0, 10.0, 41),
    "P2 normal incidence": (P2, 1000.0, 0.0, 41),
    "dielectric at a Rayleigh point": (lamellar(), 600.0, RAYLEIGH_THETA, 31),
    "cd at its Rayleigh point (normal)": (rcwa.load_structure("cd"), 400.0, 0.0, 31),
    "cd oblique, metal": (rcwa.load_structure("cd"), 633.0, 25.0, 31),
    "lossless next to lossy, metal below": (MIXED, 600.0, 20.0, 25),
    "lossless, symmetric about no point": (ASYMMETRIC, 600.0, 20.0, 25),
}
# Eigen-solves done by Hermitian solvers for unpolarized light: two per lossless layer
# (TE and TM), one where the TM pencil is not definite.
HERMITIAN_SOLVES = {"P2 oblique": 2, "P2 normal incidence": 2, "dielectric at a Rayleigh point": 2,
                    "cd at its Rayleigh point (normal)": 0, "cd oblique, metal": 0,
                    "lossless next to lossy, metal below": 2, "lossless, symmetric about no point": 2}
# Of those, the ones in real arithmetic (layers symmetric about a point: rcwa/cpp/linalg.hpp,
# real_by_phase).
REAL_SOLVES = {**HERMITIAN_SOLVES, "lossless, symmetric about no point": 0}
# Cases with a lossy patterned layer: every one here is symmetric about a point, so its
# eigen-solves are complex symmetric ones (rcwa/cpp/complex_symmetric.hpp; the others, and any
# that fails its residual check, take eig_small: tests/rcwa/test_complex_symmetric.py).
LOSSY = {"cd at its Rayleigh point (normal)", "cd oblique, metal", "lossless next to lossy, metal below"}


def _core_solutions(s, wl, theta, orders, incidence, phi=0.0):
    """The core's fast and general solutions of one point."""
    prep = prepare(s, wl, orders)
    kx0, ky0 = incident_tangential_k(math.sqrt(prep.eps_sup.real), math.radians(theta), math.radians(phi))
    args = (kx0 + prep.dkx, ky0 + prep.dky, prep.zero, prep.eps_sup, prep.eps_sub, s_direction(math.radians(phi)),
            prep.core_layers, STACK_METHOD_OF["etm"], incidence)
    return _core.solve_stack(*args, fast_paths=True), _core.solve_stack(*args, fast_paths=False)


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("pol", ["s", "p", "unpolarized"])
def test_decoupled_amplitudes_equal_the_general_path(name, pol):
    s, wl, theta, orders = CASES[name]
    fast, general = _core_solutions(s, wl, theta, orders, INCIDENCE_OF[pol])
    assert fast.decoupled and not general.decoupled
    columns = {"s": [0], "p": [1], "unpolarized": [0, 1]}[pol]
    for got, want in ((fast.reflected, general.reflected), (fast.transmitted, general.transmitted)):
        scale = max(1.0, float(np.max(np.abs(want[:, columns]))))
        assert np.max(np.abs(got[:, columns] - want[:, columns])) <= TOLERANCE_FAST * scale
        # the polarization not asked for is not solved, and says so
        assert np.all(np.isnan(got[:, [c for c in (0, 1) if c not in columns]]))


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("pol", ["s", "p", "unpolarized"])
def test_decoupled_efficiencies_equal_the_general_path(name, pol):
    s, wl, theta, orders = CASES[name]
    fast = rcwa.solve(s, wl, theta, 0.0, orders, pol)
    general = rcwa.solve(s, wl, theta, 0.0, orders, pol, fast_paths=False)
    single = ("single_polarization",) if pol != "unpolarized" else ()
    hermitian = ("hermitian_eigensolver",) if HERMITIAN_SOLVES[name] else ()
    real = ("real_arithmetic",) if REAL_SOLVES[name] else ()
    inverse = ("complex_symmetric",) if name in LOSSY else ()
    # one patterned layer: solved directly per polarization (polarized.hpp, solve_polarized_direct)
    direct = ("single_layer_direct",) if len(s.layers) == 1 else ()
    assert fast.fast_paths == ("te_tm_decoupled",) + single + direct + hermitian + real + inverse
    assert general.fast_paths == ()
    for key in ("R", "T", "T_into_substrate"):
        columns = {"s": [0], "p": [1], "unpolarized": [0, 1]}[pol]
        assert np.max(np.abs(fast.all_orders[key][:, columns] - general.all_orders[key][:, columns])) <= TOLERANCE_FAST
    for total in ("R_total", "T_total", "absorption"):
        assert abs(getattr(fast, total) - getattr(general, total)) <= TOLERANCE_FAST
    for a, b in zip(fast.orders, general.orders, strict=True):
        assert (a.m, a.R, a.T) == pytest.approx((b.m, b.R, b.T), abs=TOLERANCE_FAST)
        for key, value in a.amplitudes.items():
            if key.endswith("from_s") == (pol != "p") or pol == "unpolarized":
                assert abs(value - b.amplitudes[key]) <= TOLERANCE_FAST * max(1.0, abs(value))


def test_single_polarization_leaves_the_other_unsolved():
    result = rcwa.solve(P2, 1000.0, 10.0, 0.0, 21, "s")
    order = result.order(0)
    assert math.isfinite(order.R_s) and math.isnan(order.R_p)
    assert np.isnan(order.amplitudes["r_p_from_p"]) and np.isfinite(order.amplitudes["r_s_from_s"])


@pytest.mark.parametrize(("theta", "phi", "stack"), [
    (10.0, 30.0, "etm"),   # conical: k_y != 0 couples TE and TM
    (0.0, 90.0, "etm"),    # normal incidence, s-hat along -x: the specular order's s is TM-like
    (10.0, 0.0, "smatrix"),  # the fast path is written for the ETM stack only
])
def test_coupled_or_other_stacks_take_the_general_path(theta, phi, stack):
    result = rcwa.solve(P2, 1000.0, theta, phi, 21, "s", stack=stack)
    # P2 is lossless and symmetric about its stripe's centre; its stack is not decoupled;
    # a one-layer ETM stack is solved directly (tests/rcwa/test_direct.py)
    direct = ("single_layer_direct",) if stack == "etm" else ()
    assert result.fast_paths == direct + ("hermitian_eigensolver", "real_arithmetic")
    assert all(math.isfinite(o.R_p) for o in result.orders)


def test_two_dimensional_cells_take_no_one_dimensional_fast_path():
    # Only the mirror sectors apply to 2D cells (tests/rcwa/test_sectors.py), and only in
    # mirror planes; elsewhere a one-layer stack is solved directly (tests/rcwa/test_direct.py).
    gold2d = rcwa.load_structure("gold2d")
    assert rcwa.solve(gold2d, 550.0, 0.0, 0.0, (5, 5), "s").fast_paths == ("mirror_sectors", "single_polarization")
    assert rcwa.solve(gold2d, 550.0, 10.0, 30.0, (5, 5), "s").fast_paths == ("single_layer_direct",)


@pytest.mark.parametrize("name", CASES)
def test_lossless_layers_are_found_and_only_they(name):
    s, wl, theta, orders = CASES[name]
    fast, general = _core_solutions(s, wl, theta, orders, INCIDENCE_OF["unpolarized"])
    assert fast.hermitian_solves == HERMITIAN_SOLVES[name] and general.hermitian_solves == 0
    assert fast.real_solves == REAL_SOLVES[name] and general.real_solves == 0


@pytest.mark.parametrize("name", ["P2 oblique", "lossless next to lossy, metal below", "cd oblique, metal",
                                  "lossless, symmetric about no point"])
@pytest.mark.parametrize("phi", [30.0, 90.0])
def test_hermitian_solves_in_conical_mount_equal_the_general_path(name, phi):
    """Off the classical mount the layers couple TE and TM (general 2N path), but their
    eigen-solves are still Hermitian where the layer is lossless."""
    s, wl, theta, orders = CASES[name]
    fast, general = _core_solutions(s, wl, theta, orders, INCIDENCE_OF["unpolarized"], phi)
    assert not fast.decoupled and fast.hermitian_solves == HERMITIAN_SOLVES[name]
    assert fast.real_solves == REAL_SOLVES[name]
    for got, want in ((fast.reflected, general.reflected), (fast.transmitted, general.transmitted)):
        assert np.max(np.abs(got - want)) <= TOLERANCE_FAST * max(1.0, float(np.max(np.abs(want))))


def _stripe_matrices(eps_background: float, eps_stripe: float, x0: float, x1: float, n: int):
    """Li's 1D matrices of a stripe [x0, x1] in a unit period: E = [[eps]], Exx = [[1/eps]]^-1
    (Toeplitz, C[m, n] = c(n - m) with c(k) the Fourier coefficients of a step function)."""
    def toeplitz(inside: float, outside: float) -> np.ndarray:
        k = np.arange(-(n - 1), n)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = (np.exp(-2j * np.pi * k * x0) - np.exp(-2j * np.pi * k * x1)) / (2j * np.pi * k)
        step[k == 0] = x1 - x0
        c = (inside - outside) * step + outside * (k == 0)
        idx = np.arange(n)
        return np.ascontiguousarray(c[(idx[None, :] - idx[:, None]) + n - 1])
    E = toeplitz(eps_stripe, eps_background)
    return E, np.linalg.inv(toeplitz(1.0 / eps_stripe, 1.0 / eps_background))


@pytest.mark.parametrize("phi", [0.0, 30.0])
def test_lossless_metal_keeps_the_general_tm_solver(phi):
    """A lossless metal (eps = -9 + 0j in its stripes): its TE matrix is Hermitian, but Exx
    is not positive definite, so the TM pencil is not definite and TM keeps zgeev."""
    n = 21
    E, Exx = _stripe_matrices(1.0, -9.0, 0.2, 0.7, n)
    layer = _core.LayerInput(_core.LayerKind.LAMELLAR, 2 * np.pi * 0.05 / 0.6, 0j, [E, Exx])
    kx0, ky0 = incident_tangential_k(1.0, math.radians(20.0), math.radians(phi))
    dkx = -(np.arange(n) - n // 2) * 0.6
    args = (kx0 + dkx, np.full(n, ky0), n // 2, 1.0 + 0j, 2.25 + 0j, s_direction(math.radians(phi)), [layer],
            STACK_METHOD_OF["etm"], _core.Incidence.BOTH)
    fast, general = _core.solve_stack(*args, fast_paths=True), _core.solve_stack(*args, fast_paths=False)
    assert fast.hermitian_solves == 1
    for got, want in ((fast.reflected, general.reflected), (fast.transmitted, general.transmitted)):
        assert np.max(np.abs(got - want)) <= TOLERANCE_FAST * max(1.0, float(np.max(np.abs(want))))


@pytest.mark.parametrize("phi", [0.0, 30.0])
@pytest.mark.parametrize("eps_stripe", [2.25 + 0j, -9.0 + 1.2j])
def test_inverse_rule_layer_equals_its_explicit_exx(phi, eps_stripe):
    """A lamellar layer given as E and [[1/eps]] (inverse_rule: the core forms Exx where TM
    needs it) gives the amplitudes of the same layer given E and Exx = [[1/eps]]^-1, in
    classical mount (s, p, both) and conical mount, single solves and a sweep: the two
    differ only in which LU inverts [[1/eps]], so they agree to round-off (1e-12)."""
    n = 21
    E, Exx = _stripe_matrices(1.0, eps_stripe, 0.2, 0.7, n)
    k0d = 2 * np.pi * 0.2 / 0.6
    explicit = _core.LayerInput(_core.LayerKind.LAMELLAR, k0d, 0j, [E, Exx])
    lazy = _core.LayerInput(_core.LayerKind.LAMELLAR, k0d, 0j, [E, np.linalg.inv(Exx)], inverse_rule=True)
    kx0, ky0 = incident_tangential_k(1.0, math.radians(20.0), math.radians(phi))
    dkx = -(np.arange(n) - n // 2) * 0.6
    for incidence in (_core.Incidence.S, _core.Incidence.P, _core.Incidence.BOTH):
        got, want = (_core.solve_stack(kx0 + dkx, np.full(n, ky0), n // 2, 1.0 + 0j, 2.25 + 0j,
                                       s_direction(math.radians(phi)), [layer], STACK_METHOD_OF["etm"], incidence)
                      for layer in (lazy, explicit))
        for a, b in ((got.reflected, want.reflected), (got.transmitted, want.transmitted)):
            np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
            finite = ~np.isnan(b)
            assert np.max(np.abs(a[finite] - b[finite])) <= TOLERANCE_FAST * max(1.0, float(np.max(np.abs(b[finite]))))
    sweeps = [_core.sweep(dkx, np.zeros(n), n // 2, 1.0 + 0j, 2.25 + 0j, [layer], np.array([kx0, 0.1]),
                          np.array([ky0, 0.0]), np.array([0.0, 0.0]), np.array([1.0, 1.0]), list(range(n)))
              for layer in (lazy, explicit)]
    got, want = sweeps[0].reflected, sweeps[1].reflected
    assert np.max(np.abs(got - want)) <= TOLERANCE_FAST * max(1.0, float(np.max(np.abs(want))))

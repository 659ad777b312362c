"""The typed boundary between Python and the C++ core (rcwa/cpp/bindings.cpp, rcwa/layer_input.py).

Layers cross as LayerInput objects of a LayerKind enum, results come back as named
objects, and wrong shapes, dtypes, counts or kinds are refused where they enter with a
ValueError that names the field. The orders' wave vectors go through
workbench.core.conventions (order_kxy), and the half-spaces' kz, taken in C++ only, are
on the branch of conventions.kz_branch. The committed stub rcwa/_core.pyi is the one
nanobind's stubgen makes from the built module.
"""

from __future__ import annotations

import ast
import dataclasses
import gc
import math
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import rcwa
from rcwa import _core
from rcwa.layer_input import LayerInput, LayerKind
from rcwa.solver import STACK_METHODS as STACK_METHOD_OF
from rcwa.solver import prepare
from rcwa.sweep import kept_harmonics
from tests.rcwa.helpers import lamellar, nk, structure
from workbench.core.conventions import incident_tangential_k, kz_branch, order_kxy

STUB = Path(rcwa.__file__).parent / "_core.pyi"
# Amplitudes of one structure from a single solve and from a sweep differ only by the
# sweep's refined eigen-solves: 1e-13 measured, 1e-10 required (tests/rcwa/test_sweep.py).
TOLERANCE_SWEEP = 1e-10
# kz from C++ (std::sqrt) and numpy (npy_csqrt): two correctly rounded-ish complex square
# roots of the same argument agree to a few ulps; a wrong branch is off by 2 |kz|.
TOLERANCE_KZ_RELATIVE = 4e-16
# Fresnel amplitudes from the stack against the closed form: a bare interface is solved
# with one radian of superstrate medium between, so round-off only.
TOLERANCE_FRESNEL = 1e-13
# Directions of orders (direction cosines from asin/degrees/cos round trips).
TOLERANCE_DIRECTION = 1e-12


def _matrix(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (np.eye(n) * 2.0 + 0.1 * (rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n)))).astype(complex)


def _uniform(eps: complex, k0d: float = 0.3) -> _core.LayerInput:
    return LayerInput(LayerKind.UNIFORM, k0d, eps).core


# ---------------------------------------------------------------- layers: checked where they enter


def test_a_valid_layer_reaches_the_core_unchanged():
    E, Exx = _matrix(3), _matrix(3, 1)
    layer = LayerInput(LayerKind.LAMELLAR, 1.25, 0j, (E, Exx))
    assert layer.size == 3 and layer.core.kind is LayerKind.LAMELLAR and layer.core.k0_thickness == 1.25
    np.testing.assert_array_equal(layer.core.matrices[0], E)
    np.testing.assert_array_equal(layer.core.matrices[1], Exx)
    assert LayerInput(LayerKind.UNIFORM, 1.0, 2.25).core.permittivity == 2.25


@pytest.mark.parametrize("kind", ["lamellar", 1, None])
def test_unknown_kind_is_refused_naming_the_field(kind):
    with pytest.raises(ValueError, match=r"LayerInput\.kind: expected a LayerKind, one of \['UNIFORM', 'LAMELLAR', 'GENERAL'\]"):
        LayerInput(kind, 1.0, 2.25)


def test_the_core_has_no_unknown_kind():
    # The enum is the only way to name a kind: no sentinel, no string, no stray integer.
    assert {k.name for k in _core.LayerKind} == {"UNIFORM", "LAMELLAR", "GENERAL"}
    with pytest.raises(ValueError):
        _core.LayerKind(99)
    with pytest.raises(TypeError):
        _core.LayerInput("lamellar", 1.0, 0j, [_matrix(3), _matrix(3)])  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "kind, matrices, field",
    [
        (LayerKind.LAMELLAR, (_matrix(4),), r"LayerInput\.matrices: expected 2 for a lamellar layer"),
        (LayerKind.UNIFORM, (_matrix(4),), r"LayerInput\.matrices: expected 0 for a uniform layer"),
        (LayerKind.GENERAL, (_matrix(4),) * 4, r"LayerInput\.matrices: expected 5 for a general layer"),
        (LayerKind.LAMELLAR, (_matrix(4)[:, :3], _matrix(4)), r"matrices\[0\] \(E\): expected a square matrix.*\(4, 3\)"),
        (LayerKind.LAMELLAR, (_matrix(4), _matrix(5)), r"matrices\[1\] \(Exx\): expected shape \(4, 4\).*\(5, 5\)"),
        (LayerKind.LAMELLAR, (_matrix(4), _matrix(4).real), r"matrices\[1\] \(Exx\): expected dtype complex128.*float64"),
        (LayerKind.LAMELLAR, (_matrix(4), _matrix(4).tolist()), r"matrices\[1\] \(Exx\): expected a numpy array"),
        (LayerKind.LAMELLAR, (np.zeros(4, complex), np.zeros(4, complex)), r"matrices\[0\] \(E\).*\(4,\)"),
    ],
)
def test_wrong_matrices_are_refused_naming_the_field(kind, matrices, field):
    with pytest.raises(ValueError, match=field):
        LayerInput(kind, 1.0, 0j, matrices)


@pytest.mark.parametrize("k0d", [-1.0, math.nan, math.inf, "1.0", True])
def test_bad_thickness_is_refused(k0d):
    with pytest.raises(ValueError, match=r"LayerInput\.k0_thickness: expected a finite number >= 0"):
        LayerInput(LayerKind.UNIFORM, k0d, 2.25)


def test_bad_permittivity_is_refused():
    with pytest.raises(ValueError, match=r"LayerInput\.permittivity: expected a finite complex number"):
        LayerInput(LayerKind.UNIFORM, 1.0, complex(math.nan, 0.0))


def test_the_core_checks_layers_too():
    # Whatever bypasses rcwa.layer_input meets the same checks in C++ (std::invalid_argument
    # raised as ValueError).
    with pytest.raises(ValueError, match=r"lamellar layer: matrices: expected 2, got 1"):
        _core.LayerInput(_core.LayerKind.LAMELLAR, 1.0, 0j, [_matrix(3)])
    with pytest.raises(ValueError, match=r"general layer: matrices\[2\]: expected shape \(N, N\) with N = 3"):
        _core.LayerInput(_core.LayerKind.GENERAL, 1.0, 0j, [_matrix(3), _matrix(3), _matrix(4), _matrix(3), _matrix(3)])
    with pytest.raises(ValueError, match=r"k0_thickness must be finite and >= 0"):
        _core.LayerInput(_core.LayerKind.UNIFORM, -0.5, 2.0)


def test_the_core_checks_layers_against_the_harmonics():
    layer = LayerInput(LayerKind.LAMELLAR, 1.0, 0j, (_matrix(3), _matrix(3, 1))).core
    kx = np.linspace(-0.5, 0.5, 5)
    with pytest.raises(ValueError, match=r"layers\[0\] \(lamellar\): matrices are 3 x 3, expected 5 x 5"):
        _core.solve_stack(kx, np.zeros(5), 2, 1.0, 2.25, (0.0, 1.0), [layer])
    with pytest.raises(ValueError, match=r"zero_order: expected an index in \[0, 5\), got 5"):
        _core.solve_stack(kx, np.zeros(5), 5, 1.0, 2.25, (0.0, 1.0), [_uniform(2.0)])
    with pytest.raises(ValueError, match=r"kx and ky must be non-empty and of one length, got 5 and 4"):
        _core.solve_stack(kx, np.zeros(4), 2, 1.0, 2.25, (0.0, 1.0), [_uniform(2.0)])
    with pytest.raises(ValueError, match=r"keep: index 7 outside \[0, 5\)"):
        _core.sweep(kx, np.zeros(5), 2, 1.0, 2.25, [_uniform(2.0)], np.zeros(1), np.zeros(1), np.zeros(1),
                    np.ones(1), [7])


def test_prepared_structure_checks_its_arrays():
    prep = prepare(lamellar(), 550.0, 11)
    with pytest.raises(ValueError, match=r"PreparedStructure\.dkx: expected float64 of shape \(11,\)"):
        dataclasses.replace(prep, dkx=prep.dkx[:-1])
    with pytest.raises(ValueError, match=r"PreparedStructure\.dky: expected float64 of shape \(11,\)"):
        dataclasses.replace(prep, dky=prep.dky.astype(np.float32))
    with pytest.raises(ValueError, match=r"PreparedStructure\.zero: expected an index in \[0, 11\)"):
        dataclasses.replace(prep, zero=11)
    small = prepare(lamellar(), 550.0, 7)
    with pytest.raises(ValueError, match=r"PreparedStructure\.layers\[0\]: expected 11 x 11 matrices.*got 7 x 7"):
        dataclasses.replace(prep, layers=small.layers)


# ---------------------------------------------------------------- results: named fields


def test_stack_solution_names_the_fresnel_amplitudes():
    """A bare air/glass interface: |r_s| = |r_p| = (n2 - n1) / (n2 + n1) at normal incidence,
    and r_p = 0 at Brewster's angle (Born & Wolf, 7th ed., Sec. 1.5.2-1.5.3)."""
    n1, n2 = 1.0, 1.5
    sol = _core.solve_stack(np.zeros(1), np.zeros(1), 0, n1**2, n2**2, (0.0, 1.0), [_uniform(n1**2, 1.0)])
    assert isinstance(sol, _core.StackSolution)
    assert sol.reflected.shape == sol.transmitted.shape == (2, 2)
    assert sol.kz_superstrate.shape == sol.kz_substrate.shape == (1,)
    fresnel = (n2 - n1) / (n2 + n1)
    assert abs(sol.reflected[0, 0]) == pytest.approx(fresnel, abs=TOLERANCE_FRESNEL)  # s out, s in
    assert abs(sol.reflected[1, 1]) == pytest.approx(fresnel, abs=TOLERANCE_FRESNEL)  # p out, p in
    assert abs(sol.reflected[1, 0]) < TOLERANCE_FRESNEL  # no s -> p at a plane interface
    assert sol.kz_superstrate[0] == n1 and sol.kz_substrate[0] == n2

    kx = n1 * math.sin(math.atan(n2 / n1))
    brewster = _core.solve_stack(np.array([kx]), np.zeros(1), 0, n1**2, n2**2, (0.0, 1.0), [_uniform(n1**2, 1.0)])
    assert abs(brewster.reflected[1, 1]) < TOLERANCE_FRESNEL
    assert abs(brewster.reflected[0, 0]) > 0.1


def test_result_arrays_are_read_only_views_that_keep_their_result_alive():
    args = (np.array([0.0, 0.4]), np.zeros(2), 0, 1.0, complex(0.2, 3.4), (0.0, 1.0), [_uniform(2.0)])
    reflected = _core.solve_stack(*args).reflected  # the StackSolution itself is dropped here
    gc.collect()
    _core.solve_stack(*args)  # reuse freed memory, if any was freed
    np.testing.assert_array_equal(reflected, _core.solve_stack(*args).reflected)
    assert not reflected.flags.writeable


def test_sweep_solution_is_the_single_solutions_kept_rows():
    s, orders, keep = lamellar(), 21, 7
    prep = prepare(s, 550.0, orders)
    idx = kept_harmonics(prep.harmonics.m, prep.harmonics.n, (keep,))
    theta, phi = np.radians([0.0, 20.0, 35.0]), np.radians([0.0, 30.0, 110.0])
    kx0, ky0 = np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi)
    sw = _core.sweep(prep.dkx, prep.dky, prep.zero, prep.eps_sup, prep.eps_sub, prep.core_layers, kx0, ky0,
                     -np.sin(phi), np.cos(phi), [int(i) for i in idx], STACK_METHOD_OF["etm"], 1)
    assert isinstance(sw, _core.SweepSolution)
    assert sw.reflected.shape == sw.transmitted.shape == (3, 2 * keep, 2)
    assert sw.kz_superstrate.shape == sw.kz_substrate.shape == (3, keep)
    assert sw.eigen_solves == 2 * 3 and 0 <= sw.eigen_refined <= sw.eigen_solves  # one lamellar layer, 3 kx0
    rows = np.concatenate([idx, orders + idx])
    for p in range(3):
        one = _core.solve_stack(kx0[p] + prep.dkx, ky0[p] + prep.dky, prep.zero, prep.eps_sup, prep.eps_sub,
                                (-math.sin(phi[p]), math.cos(phi[p])), prep.core_layers)
        np.testing.assert_allclose(sw.reflected[p], one.reflected[rows], rtol=0, atol=TOLERANCE_SWEEP)
        np.testing.assert_allclose(sw.transmitted[p], one.transmitted[rows], rtol=0, atol=TOLERANCE_SWEEP)
        np.testing.assert_array_equal(sw.kz_superstrate[p], one.kz_superstrate[idx])
        np.testing.assert_array_equal(sw.kz_substrate[p], one.kz_substrate[idx])


def test_eig_from_guess_names_values_and_vectors():
    A = (np.diag([1.0, 2.0, 4.0]) + 0.01).astype(np.complex128)
    decomposition = _core.eig_from_guess(A, np.eye(3, dtype=complex))
    assert isinstance(decomposition, _core.EigenDecomposition)
    np.testing.assert_allclose(A @ decomposition.vectors, decomposition.vectors * decomposition.values, atol=1e-13)
    with pytest.raises(ValueError, match=r"guess: expected 3 x 3"):
        _core.eig_from_guess(A, np.eye(2, dtype=complex))


def test_the_gil_is_released_while_the_core_sweeps():
    """The main thread runs Python while another thread is inside the core.

    Decided by order of events, not by a clock (issue 23): with the interpreter's switch
    interval made huge, a thread holding the GIL keeps it until it blocks or releases it.
    The worker sets ``entered`` and calls the core; the main thread, waiting on ``entered``,
    can only run again when the worker releases the GIL. Released inside the core, the main
    thread runs while the sweep goes on and sees ``finished`` still unset; held, it runs
    only after the worker has returned and set ``finished``. The sweep (30 directions, about
    a quarter of a second on an idle core) leaves the main thread that long to be scheduled.
    """
    s = rcwa.load_structure("cd")
    prep = prepare(s, 550.0, 61)
    idx = [int(i) for i in kept_harmonics(prep.harmonics.m, prep.harmonics.n, (21,))]
    kx0 = np.linspace(0.0, 0.9, 30)
    args = (prep.dkx, prep.dky, prep.zero, prep.eps_sup, prep.eps_sub, prep.core_layers, kx0, np.zeros(kx0.size),
            np.zeros(kx0.size), np.ones(kx0.size), idx, STACK_METHOD_OF["etm"], 1)
    entered, finished = threading.Event(), threading.Event()

    def sweep() -> None:
        entered.set()
        _core.sweep(*args)
        finished.set()

    previous = sys.getswitchinterval()
    sys.setswitchinterval(1000.0)  # no forced GIL hand-over during the test
    try:
        worker = threading.Thread(target=sweep)
        worker.start()
        entered.wait()
        seen_during_the_sweep = not finished.is_set()
        worker.join()
    finally:
        sys.setswitchinterval(previous)
    assert finished.is_set()
    assert seen_during_the_sweep, "the main thread ran only after the core returned: the GIL was held"


# ---------------------------------------------------------------- conventions


def test_order_offsets_come_from_the_conventions_1d():
    s, wl_um = lamellar(period=1.3), 0.55
    prep = prepare(s, 1000 * wl_um, 21)
    kx, ky = order_kxy(0.0, 0.0, prep.harmonics.m, prep.harmonics.n, (1.3,), wl_um)
    np.testing.assert_array_equal(prep.dkx, kx)
    np.testing.assert_array_equal(prep.dky, ky)
    assert prep.dkx[prep.harmonics.m == 1][0] < 0  # Eq. 2: order +1 goes toward -x


def test_orders_leave_where_the_conventions_put_them_2d():
    period, wl, theta, phi = (1.0, 1.4), 480.0, 20.0, 35.0
    s = structure(list(period), nk(1.0), nk(1.5), [{"thickness": 0.2, "material": nk(1.0),
                  "shapes": [{"material": nk(2.0), "circle": {"center": [0.3, 0.4], "radius": 0.25}}]}])
    prep = prepare(s, wl, (5, 5))
    kx, ky = order_kxy(0.0, 0.0, prep.harmonics.m, prep.harmonics.n, period, wl / 1000)
    np.testing.assert_array_equal(prep.dkx, kx)
    np.testing.assert_array_equal(prep.dky, ky)

    result = rcwa.solve(s, wl, theta, phi, (5, 5))
    kx_inc, ky_inc = incident_tangential_k(1.0, math.radians(theta), math.radians(phi))
    reflected = [o for o in result.orders if o.propagating_R]
    assert len(reflected) >= 4 and any(o.n != 0 for o in reflected)
    for o in reflected:
        kx_m, ky_n = order_kxy(kx_inc, ky_inc, o.m, o.n, period, wl / 1000)
        th, ph = map(math.radians, o.direction_R)
        assert math.sin(th) * math.cos(ph) == pytest.approx(float(kx_m), abs=TOLERANCE_DIRECTION)
        assert math.sin(th) * math.sin(ph) == pytest.approx(float(ky_n), abs=TOLERANCE_DIRECTION)


@pytest.mark.parametrize(
    "eps_substrate",
    [2.25, complex(2.25, 0.1), complex(-10.0, 1.0), complex(2.25, -0.0), complex(-4.0, -0.0), complex(0.5, 1e-30)],
    ids=["lossless", "lossy", "metal", "lossless -0.0j", "lossless plasma -0.0j", "barely lossy"],
)
def test_half_space_kz_follow_the_conventions_branch(eps_substrate):
    """The core's kz of the superstrate and substrate equal conventions.kz_branch: propagating,
    grazing (kx^2 = eps exactly: kx = 1 in air, kx = 1.5 in the substrate of eps 2.25),
    evanescent and lossy orders, and a -0.0j permittivity that a naive sqrt would send to
    the wrong sheet."""
    kx = np.array([0.0, 0.5, 1.0, 1.2, 1.5, 2.0, 3.5])
    ky = np.array([0.0, 0.3, 0.0, -0.4, 0.0, 0.7, 0.0])
    eps_sup = 1.0
    sol = _core.solve_stack(kx, ky, 0, eps_sup, eps_substrate, (0.0, 1.0), [_uniform(2.0)])
    for got, eps in ((sol.kz_superstrate, complex(eps_sup)), (sol.kz_substrate, complex(eps_substrate))):
        expected = kz_branch(eps - kx**2 - ky**2)
        np.testing.assert_allclose(got, expected, rtol=TOLERANCE_KZ_RELATIVE, atol=0)
        assert np.all((got.imag > 0) | ((got.imag == 0) & (got.real >= 0)))
    assert sol.kz_superstrate[2] == 0  # grazing in the superstrate, exactly


# ---------------------------------------------------------------- the stub


def _stub_names(text: str) -> set[str]:
    return {node.name for node in ast.parse(text).body if isinstance(node, (ast.ClassDef, ast.FunctionDef))}


def test_stub_declares_every_public_name_of_the_module():
    public = {name for name in dir(_core) if not name.startswith("_")}
    assert public == _stub_names(STUB.read_text())


def test_committed_stub_is_the_generated_one(tmp_path):
    pytest.importorskip("nanobind.stubgen", reason="nanobind (a build requirement) generates the stub")
    out = tmp_path / "_core.pyi"
    subprocess.run([sys.executable, "-m", "nanobind.stubgen", "-q", "-m", "rcwa._core", "-o", str(out)], check=True)
    assert STUB.read_text() == out.read_text(), (
        "rcwa/_core.pyi is stale: regenerate it with "
        "`.venv/bin/python -m nanobind.stubgen -m rcwa._core -o rcwa/_core.pyi` after `make install`"
    )


def test_inverse_rule_is_refused_off_lamellar_layers():
    """inverse_rule says the second lamellar matrix is [[1/eps]]: on another kind it would be
    meaningless, so both boundaries refuse it, naming the field."""
    with pytest.raises(ValueError, match=r"LayerInput\.inverse_rule"):
        LayerInput(LayerKind.GENERAL, 1.0, 0j, (_matrix(3),) * 5, inverse_rule=True)
    with pytest.raises(ValueError, match="inverse_rule applies to lamellar layers only"):
        _core.LayerInput(_core.LayerKind.UNIFORM, 1.0, 2.25, [], inverse_rule=True)


def test_a_lamellar_layer_from_its_profile_is_checked_by_the_core():
    """The core builds a 1D layer's matrices from its profile (rcwa/cpp/profile.hpp; their
    values: tests/rcwa/test_factorization.py); an even harmonic count or an empty segment
    cannot describe one and is refused, naming what is wrong."""
    layer = _core.LayerInput.lamellar(1.0, 2.0, [(0.0, 0.5, 2.25 + 0j), (0.5, 2.0, 1.0 + 0j)], 5)
    assert layer.kind == _core.LayerKind.LAMELLAR and layer.size == 5 and layer.inverse_rule
    with pytest.raises(ValueError, match="harmonics must be odd"):
        _core.LayerInput.lamellar(1.0, 2.0, [(0.0, 2.0, 1.0 + 0j)], 4)
    with pytest.raises(ValueError, match="x1 > x0"):
        _core.LayerInput.lamellar(1.0, 2.0, [(0.5, 0.5, 1.0 + 0j)], 5)

"""One RCWA solve: structure + wavelength + angles + truncation -> efficiencies.

The method is the Fourier modal method / RCWA ([Moharam 1981]; the stable formulation of
[Moharam 1995a] and [Moharam 1995b]) with the
factorization rules of rcwa.factorization, layer eigenmodes and the enhanced transmittance
matrix stack in C++ (rcwa/cpp). This module converts units, validates the request, builds
the Fourier matrices and turns the core's amplitudes and efficiencies into a result. Conventions:
workbench.core.conventions.

Fast paths (``solve(fast_paths=True)``, the default). Where a 1D stack has every k_y = 0
(classical mount) and the ETM stack is used, TE and TM are solved apart on N x N blocks
(rcwa/cpp/polarized.hpp), and for ``pol="s"`` or ``"p"`` only that one: the other
polarization's efficiencies and amplitudes are then NaN. Lossless 1D layers (real
permittivity everywhere) are solved with Hermitian eigen-solvers (zheevd / zhegvd), their
inverses taken from the eigenvectors, and in real arithmetic (dsyevd / dsygvd,
"real_arithmetic") where the layer is symmetric about a point (moving the origin there
makes its matrices real). A 2D cell with a mirror (rcwa.symmetry) the incidence respects
(x -> -x at k_x = 0: normal incidence or phi = +-90; y -> -y at k_y = 0: phi = 0 or 180)
is solved in mirror-symmetry sectors (rcwa/cpp/sectors.hpp), only those the asked
polarization excites (for ``"s"`` or ``"p"`` the other's values are NaN). Otherwise a
stack of one patterned layer (2D, or 1D off the classical mount) is solved as one 4N x 4N
boundary system ("single_layer_direct", rcwa/cpp/stack.cpp) instead of through the
layer's W^-1 and V^-1. Lossy 1D layers below 75 harmonics take their eigenvalues from the
QR algorithm alone and their eigenvectors by inverse iteration ("inverse_iteration",
rcwa/cpp/linalg.hpp eig_small), 20 % faster than zgeev there. Lossy 1D layers symmetric
about a point (their matrices complex symmetric once the origin is moved there) are solved
before that as complex symmetric problems ("complex_symmetric",
rcwa/cpp/complex_symmetric.hpp: tridiagonal form by complex-orthogonal reflectors, QL,
inverse iteration, one refinement step against the layer's own matrix), each accepted only
on a residual check and otherwise solved as above; about 2x faster than eig_small at 61
harmonics.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rcwa import _core, symmetry
from rcwa.factorization import HarmonicIndices, lamellar_profile, permittivity_matrices, resolve_rule
from rcwa.layer_input import LayerInput, LayerKind
from rcwa.materials import Material
from rcwa.result import OrderResult, SolveResult
from rcwa.structure import Structure
from workbench.core.conventions import Polarization, incident_tangential_k, order_kxy
from workbench.core.errors import UserInputError

# One BLAS thread inside the core: its matrices are small (2N <= ~1000), OpenBLAS's idle
# threads spin after each call and then starve numpy's own BLAS on a 2-core machine
# (measured: a 2D normal-vector solve at 11 x 11 took 177 ms with 2 threads, 64 ms with
# 1), and sweeps parallelize across solves instead. Set once, here, at import.
_core.set_blas_threads(1)

# The superstrate must be lossless for the incident power to be defined; an index whose
# imaginary part is below this (relative) is treated as lossless.
LOSSLESS_TOLERANCE = 1e-12
MAX_THETA_DEG = 90.0
# The stack methods by the names the command line and ``solve(stack=...)`` use (rcwa/cpp/stack.hpp):
# the enhanced transmittance matrix [Moharam 1995b] and Redheffer's star product of
# layer scattering matrices [Rumpf 2011].
STACK_METHODS: dict[str, _core.StackMethod] = {
    "etm": _core.StackMethod.ENHANCED_TRANSMITTANCE, "smatrix": _core.StackMethod.SCATTERING_MATRIX,
}


@dataclass(frozen=True, eq=False)  # eq=False: identity, since numpy arrays have no truth value
class PreparedStructure:
    """Everything about a request that does not depend on the incident direction.

    Checked on creation (ValueError naming the field) before any of it reaches C++: N
    harmonics, ``dkx`` and ``dky`` float64 of shape (N,), ``zero`` in [0, N), every
    patterned layer's matrices N x N.
    """

    structure: Structure
    wavelength_nm: float
    counts: tuple[int, ...]
    rule: str
    harmonics: HarmonicIndices
    dkx: np.ndarray  # kx of harmonic i is kx0 + dkx[i] (normalized by k0)
    dky: np.ndarray
    zero: int
    eps_sup: complex
    eps_sub: complex
    layers: tuple[LayerInput, ...]

    def __post_init__(self) -> None:
        n = int(np.prod(self.counts))
        for name in ("dkx", "dky"):
            value = getattr(self, name)
            if not isinstance(value, np.ndarray) or value.dtype != np.float64 or value.shape != (n,):
                got = (value.shape, str(value.dtype)) if isinstance(value, np.ndarray) else type(value).__name__
                raise ValueError(f"PreparedStructure.{name}: expected float64 of shape ({n},), got {got!r}")
        if not 0 <= self.zero < n:
            raise ValueError(f"PreparedStructure.zero: expected an index in [0, {n}), got {self.zero!r}")
        for i, layer in enumerate(self.layers):
            if not isinstance(layer, LayerInput):
                raise ValueError(f"PreparedStructure.layers[{i}]: expected a LayerInput, got {type(layer).__name__}")
            if layer.kind != LayerKind.UNIFORM and layer.size != n:
                raise ValueError(f"PreparedStructure.layers[{i}]: expected {n} x {n} matrices (one row per "
                                 f"harmonic), got {layer.size} x {layer.size}")

    @property
    def core_layers(self) -> list[_core.LayerInput]:
        return [layer.core for layer in self.layers]


def prepare(structure: Structure, wavelength_nm: float, orders: int | Sequence[int],
            factorization: str = "auto") -> PreparedStructure:
    """Validate the request and build every layer's Fourier matrices (direction-free)."""
    counts = _order_counts(orders, structure.dimension)
    rule = resolve_rule(factorization, structure.dimension, structure.layers)
    wl_um = _positive(wavelength_nm, "wavelength") / 1000.0
    eps_of = _permittivity_lookup(structure, float(wavelength_nm))
    eps_sup, eps_sub = eps_of(structure.superstrate), eps_of(structure.substrate)
    if abs(eps_sup.imag) > LOSSLESS_TOLERANCE * abs(eps_sup) or eps_sup.real <= 0:
        raise UserInputError(
            "the superstrate must be a lossless dielectric (the incident power is measured there)",
            file=structure.source, field="superstrate", expected="k = 0 and n > 0", got=complex(np.sqrt(eps_sup)),
        )
    h, dkx, dky, zero = _harmonics(structure.period, counts, wl_um)
    # A zero-thickness layer is the identity in either stack; it is left out rather than
    # passed on, since at a Rayleigh point (k_z = 0) its mode matrices are singular.
    layers = tuple(_layer_input(layer, structure, eps_of, h, rule, 2 * math.pi / wl_um)
                   for layer in structure.layers if layer.thickness > 0)
    if not layers:
        # A bare interface: where an order grazes both half-spaces (k_z = 0 in each, e.g. the
        # same medium on both sides at a Rayleigh point) its reflected and transmitted
        # waves are one field and the matching system is singular. A uniform layer of the
        # superstrate's medium (one radian of phase thick) changes nothing physically and
        # gives those orders a finite layer's well-defined modes.
        layers = (LayerInput(LayerKind.UNIFORM, 1.0, complex(eps_sup.real, 0.0)),)
    return PreparedStructure(structure, float(wavelength_nm), counts, rule, h, dkx, dky, zero,
                             complex(eps_sup.real, 0.0), eps_sub, layers)


def solve(
    structure: Structure,
    wavelength_nm: float,
    theta_deg: float,
    phi_deg: float,
    orders: int | Sequence[int],
    pol: str | Polarization = Polarization.UNPOLARIZED,
    factorization: str = "auto",
    stack: str = "etm",
    fast_paths: bool = True,
) -> SolveResult:
    """Diffraction efficiencies of ``structure`` for one incident plane wave.

    Parameters
    ----------
    wavelength_nm: vacuum wavelength in nanometres.
    theta_deg, phi_deg: incidence angles in degrees (workbench.core.conventions): polar angle
        in the superstrate, ``0 <= theta < 90``, and azimuth of the tangential wave vector.
    orders: retained harmonics per direction, odd: ``N`` (1D) or ``(Nx, Ny)`` (2D; an
        int means ``(N, N)``).
    pol: ``"s"``, ``"p"`` or ``"unpolarized"`` (the mean of s and p efficiencies).
    factorization: ``"auto"``, ``"li"``, ``"nv"`` or ``"laurent"`` (rcwa.factorization).
    stack: how layers are combined (rcwa/cpp/stack.cpp), both free of growing exponentials:
        ``"etm"``, the enhanced transmittance matrix ([Moharam 1995b]; one bottom-up
        sweep, the default: half the time of the other for one-sided solves), or
        ``"smatrix"``, Redheffer's star product of layer scattering matrices [Rumpf 2011].
        They agree to round-off (tests/rcwa/test_stack_methods.py).
    fast_paths: take the fast paths where they apply (this module's docstring lists them;
        ``SolveResult.fast_paths`` names what was used). False forces the general path (to
        check the fast ones: tests/rcwa/test_fast_paths.py, tests/rcwa/test_sectors.py); the
        two agree to 1e-12.
    """
    pol = _polarization(pol)
    method = stack_method(stack)
    theta, phi = _angles(theta_deg, phi_deg)
    prep = prepare(structure, wavelength_nm, orders, factorization)
    kx0, ky0 = incident_tangential_k(math.sqrt(prep.eps_sup.real), theta, phi)
    kx, ky = kx0 + prep.dkx, ky0 + prep.dky
    mirrors = mirrors_of(prep) if fast_paths and may_respect_a_mirror(kx0, ky0) else []
    sol = _core.solve_stack(kx, ky, prep.zero, prep.eps_sup, prep.eps_sub, s_direction(phi), prep.core_layers,
                            method, INCIDENCE_OF[pol.value], fast_paths, mirrors)
    return _result(prep, theta_deg, phi_deg, pol, kx, ky, sol, _fast_paths(sol, pol))


# The incident polarizations the core must answer for each requested one.
INCIDENCE_OF = {"s": _core.Incidence.S, "p": _core.Incidence.P, "unpolarized": _core.Incidence.BOTH}


# A mirror x -> -x can only be respected at k_x0 = 0, y -> -y at k_y0 = 0; the core decides
# with its own, tighter test (rcwa/cpp/sectors.cpp, 1e-14), so this gate only skips building
# the mirrors (0.2 ms a 2D solve) where none can apply.
MIRROR_GATE = 1e-12


def may_respect_a_mirror(kx0: float, ky0: float) -> bool:
    """Whether the incident wave vector lies in a plane x = 0 or y = 0 (to MIRROR_GATE)."""
    return abs(kx0) <= MIRROR_GATE or abs(ky0) <= MIRROR_GATE


def mirrors_of(prep: PreparedStructure) -> list[symmetry.CoreMirror]:
    """A 2D cell's mirrors for the core's sector solve (rcwa.symmetry.core_mirrors); none
    for 1D cells (their classical mount decouples TE and TM instead) or without layers."""
    if prep.structure.dimension != 2 or not any(layer.kind == LayerKind.GENERAL for layer in prep.layers):
        return []
    k0 = 2 * math.pi / (prep.wavelength_nm / 1000.0)
    return symmetry.core_mirrors(prep.structure, prep.harmonics.m, prep.harmonics.n, prep.dkx, prep.dky, k0)


def _fast_paths(sol: _core.StackSolution, pol: Polarization) -> tuple[str, ...]:
    """Names of the fast paths the core took (reported in SolveResult.fast_paths)."""
    paths: tuple[str, ...] = ()
    single = ("single_polarization",) if pol != Polarization.UNPOLARIZED else ()
    if sol.decoupled:
        paths += ("te_tm_decoupled",) + single
    if sol.sectors_total:
        paths += ("mirror_sectors",) + single
    if sol.direct:
        paths += ("single_layer_direct",)
    if sol.hermitian_solves:
        paths += ("hermitian_eigensolver",)
    if sol.real_solves:
        paths += ("real_arithmetic",)
    if sol.inverse_iteration_solves:
        paths += ("inverse_iteration",)
    if sol.complex_symmetric_solves:
        paths += ("complex_symmetric",)
    return paths


def stack_method(stack: str) -> _core.StackMethod:
    """The core's stack method named ``stack`` (STACK_METHODS); UserInputError for an unknown name."""
    if stack not in STACK_METHODS:
        raise UserInputError("unknown stack method", field="stack", expected=f"one of {tuple(STACK_METHODS)}",
                             got=stack)
    return STACK_METHODS[stack]


def s_direction(phi: float) -> tuple[float, float]:
    """s-hat of the plane of incidence at azimuth phi (used where kx = ky = 0)."""
    return -math.sin(phi), math.cos(phi)


# ---------------------------------------------------------------- validation


def _polarization(pol: str | Polarization) -> Polarization:
    try:
        return Polarization(pol)
    except ValueError:
        raise UserInputError("unknown polarization", field="pol", expected="s, p or unpolarized", got=pol) from None


MEMORY_FRACTION = 0.5  # a solve may take at most this share of the machine's memory


def _order_counts(orders: int | Sequence[int], dimension: int) -> tuple[int, ...]:
    if isinstance(orders, (int, np.integer)):
        values: tuple = (orders,) * dimension
    elif isinstance(orders, (list, tuple, np.ndarray)):
        values = tuple(orders)
    else:
        raise UserInputError("the number of retained harmonics must be a positive odd integer (or one per direction)",
                             field="orders", expected="1, 3, 5, ... or (NX, NY)", got=orders)
    if len(values) != dimension:
        raise UserInputError(
            f"a {dimension}D structure needs {dimension} order count(s)", field="orders",
            expected="N" if dimension == 1 else "NX,NY", got=orders,
        )
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1 or v % 2 == 0:
            raise UserInputError(
                "the number of retained harmonics must be a positive odd integer (symmetric about order 0)",
                field="orders", expected="1, 3, 5, ...", got=orders,
            )
    counts = tuple(int(v) for v in values)
    _check_memory(counts)
    return counts


def _check_memory(counts: tuple[int, ...]) -> None:
    """Refuse a truncation whose matrices would not fit: the core holds about a dozen
    complex 2N x 2N matrices per layer at once (N = the product of the counts)."""
    harmonics = math.prod(counts)
    need = 12 * (2 * harmonics) ** 2 * 16
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return
    if need > MEMORY_FRACTION * total:
        raise UserInputError(
            f"{harmonics} harmonics need about {need / 2**30:.0f} GiB for the solver's matrices, more than half of "
            f"this machine's {total / 2**30:.0f} GiB", field="orders",
            expected=f"fewer harmonics (at most about {_max_harmonics(total)} in all)",
            got=counts if len(counts) > 1 else counts[0])


def _max_harmonics(total_bytes: int) -> int:
    return int(math.sqrt(MEMORY_FRACTION * total_bytes / (12 * 16)) / 2)


def _positive(value: float, name: str) -> float:
    if not (isinstance(value, (int, float, np.floating)) and math.isfinite(value) and value > 0):
        raise UserInputError("must be a positive number", field=name, got=value)
    return float(value)


def _angles(theta_deg: float, phi_deg: float) -> tuple[float, float]:
    for value, name in ((theta_deg, "theta"), (phi_deg, "phi")):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise UserInputError("must be a number of degrees", field=name, got=value)
    if not (math.isfinite(theta_deg) and 0.0 <= theta_deg < MAX_THETA_DEG):
        raise UserInputError("the polar angle must be in [0, 90) degrees", field="theta", expected="0 <= theta < 90",
                             got=theta_deg)
    if not math.isfinite(phi_deg):
        raise UserInputError("must be a finite number of degrees", field="phi", got=phi_deg)
    return math.radians(theta_deg), math.radians(phi_deg)


def _permittivity_lookup(structure: Structure, wavelength_nm: float):
    cache: dict[int, complex] = {}

    def eps_of(material: Material) -> complex:
        key = id(material)
        if key not in cache:
            try:
                cache[key] = complex(np.asarray(material.epsilon(wavelength_nm)).item())
            except UserInputError as exc:
                raise exc.located(file=structure.source, field_prefix=structure.field_of(material)) from None
        return cache[key]

    return eps_of


# ---------------------------------------------------------------- assembly


def _harmonics(period: tuple[float, ...], counts: tuple[int, ...], wl_um: float):
    """Retained harmonics and their offsets from the incident wave vector.

    The offsets are the orders' ``(kx, ky) / k0`` for a zero incident wave vector, by
    workbench.core.conventions.order_kxy (the sign of [Lange 2021, Eq. 2]), so that
    harmonic i of a direction has ``kx0 + dkx[i]``, ``ky0 + dky[i]``.
    """
    ms = np.arange(counts[0]) - counts[0] // 2
    if len(period) == 1:
        h = HarmonicIndices(ms, np.zeros_like(ms))
    else:
        ns = np.arange(counts[1]) - counts[1] // 2
        M, N = np.meshgrid(ms, ns, indexing="ij")
        h = HarmonicIndices(M.ravel(), N.ravel())
    dkx, dky = order_kxy(0.0, 0.0, h.m, h.n, tuple(period), wl_um)
    zero = int(np.flatnonzero((h.m == 0) & (h.n == 0))[0])
    return h, np.ascontiguousarray(dkx, dtype=float), np.ascontiguousarray(dky, dtype=float), zero


def _layer_input(layer, structure: Structure, eps_of, h: HarmonicIndices, rule: str, k0: float) -> LayerInput:
    k0d = k0 * layer.thickness
    if layer.is_uniform or all(eps_of(s.material) == eps_of(layer.material) for s in layer.shapes):
        # No contrast at this wavelength: a uniform layer, solved without an eigen-solve.
        return LayerInput(LayerKind.UNIFORM, k0d, eps_of(layer.material))
    if structure.dimension == 1:
        # Li's inverse rule leaves Exx = [[1/eps]]^-1 to the core, which forms it only where a
        # TM family needs it (not for s in classical mount).
        return LayerInput.lamellar(k0d, structure.period[0], lamellar_profile(layer, structure.period[0], eps_of),
                                   h.m.size, inverse_rule=rule != "laurent")
    pm = permittivity_matrices(layer, structure.period, eps_of, h, rule)
    zero = np.zeros_like(pm.E)
    exy = pm.exy if pm.exy is not None else zero
    eyx = pm.eyx if pm.eyx is not None else zero
    return LayerInput(LayerKind.GENERAL, k0d, 0j, (pm.E, pm.exx, exy, eyx, pm.eyy))


def _result(prep: PreparedStructure, theta_deg, phi_deg, pol, kx, ky, sol: _core.StackSolution,
            fast_paths: tuple[str, ...] = ()) -> SolveResult:
    h = prep.harmonics
    # Fluxes through z = const per unit incident power (rcwa/cpp/efficiency.hpp).
    R, T, T_into = sol.efficiencies(prep.zero, prep.eps_sup, prep.eps_sub)
    r, t, kz_sup, kz_sub = sol.reflected, sol.transmitted, sol.kz_superstrate, sol.kz_substrate
    # A column, not a weighted sum, for one polarization: the other may be NaN (not solved).
    if pol.value == "unpolarized":
        half = np.array([0.5, 0.5])
        R_pol, T_pol = R @ half, T @ half
    else:
        column = 0 if pol.value == "s" else 1
        R_pol, T_pol = R[:, column], T[:, column]

    def build_orders() -> list[OrderResult]:
        return _order_results(prep, kx, ky, r, t, R, T, R_pol, T_pol)

    R_total = float(np.sum(R_pol))
    T_total = float(np.sum(T_pol))
    return SolveResult(
        structure=prep.structure.name, wavelength_nm=prep.wavelength_nm, theta_deg=float(theta_deg), phi_deg=float(phi_deg),
        pol=pol.value, orders_retained=prep.counts, factorization=prep.rule, R_total=R_total, T_total=T_total,
        absorption=1.0 - R_total - T_total, order_builder=build_orders,
        all_orders={"m": h.m, "n": h.n, "R": R, "T": T, "T_into_substrate": T_into, "kz_superstrate": kz_sup,
                    "kz_substrate": kz_sub},
        fast_paths=fast_paths,
    )


def _order_results(prep: PreparedStructure, kx: np.ndarray, ky: np.ndarray, r: np.ndarray, t: np.ndarray,
                   R: np.ndarray, T: np.ndarray, R_pol: np.ndarray, T_pol: np.ndarray) -> list[OrderResult]:
    """The propagating orders' OrderResult objects (SolveResult.orders, built on first use)."""
    n = kx.size
    eps_sup, eps_sub, h = prep.eps_sup, prep.eps_sub, prep.harmonics
    lossless_sub = eps_sub.imag == 0.0 and eps_sub.real > 0
    kt = np.hypot(kx, ky)
    prop_R = (eps_sup.real - kt**2) > 0
    prop_T = ((eps_sub.real - kt**2) > 0) if lossless_sub else np.zeros(n, dtype=bool)
    azimuth = np.degrees(np.arctan2(ky, kx))
    # Python scalars in bulk (tolist), not one numpy scalar at a time: the same values.
    rows = np.flatnonzero(prop_R | prop_T)
    amp_names = ("r_s_from_s", "r_p_from_s", "r_s_from_p", "r_p_from_p",
                 "t_s_from_s", "t_p_from_s", "t_s_from_p", "t_p_from_p")
    amps = np.stack([r[rows, 0], r[n + rows, 0], r[rows, 1], r[n + rows, 1],
                     t[rows, 0], t[n + rows, 0], t[rows, 1], t[n + rows, 1]], axis=1).tolist()
    eff = np.stack([R_pol[rows], T_pol[rows], R[rows, 0], R[rows, 1], T[rows, 0], T[rows, 1]], axis=1).tolist()
    ms, ns, kts, azs = h.m[rows].tolist(), h.n[rows].tolist(), kt[rows].tolist(), azimuth[rows].tolist()
    flags_R, flags_T = prop_R[rows].tolist(), prop_T[rows].tolist()
    # Polar angle of a propagating order (degrees from the normal): asin(kt / n) in its medium.
    root_sup, root_sub = math.sqrt(eps_sup.real), math.sqrt(eps_sub.real) if lossless_sub else 1.0
    # The media and the incident wave's cosine, for the orders' Jones matrices (rcwa.polarimetry).
    kt_in = float(kt[prep.zero])
    media = (root_sup, root_sub if lossless_sub else math.nan, math.sqrt(max(0.0, 1.0 - kt_in**2 / eps_sup.real)))
    orders = []
    for j in range(rows.size):
        on_R, on_T = flags_R[j], flags_T[j]
        R_j, T_j, R_s, R_p, T_s, T_p = eff[j]
        orders.append(
            OrderResult.from_fields(dict(
                m=ms[j], n=ns[j], R=R_j if on_R else 0.0, T=T_j if on_T else 0.0,
                R_s=R_s, R_p=R_p, T_s=T_s, T_p=T_p, propagating_R=on_R, propagating_T=on_T,
                direction_R=(math.degrees(math.asin(min(1.0, kts[j] / root_sup))), azs[j]) if on_R else None,
                direction_T=(math.degrees(math.asin(min(1.0, kts[j] / root_sub))), azs[j]) if on_T else None,
                amplitudes=dict(zip(amp_names, amps[j], strict=True)), media=media,
            ))
        )
    return orders

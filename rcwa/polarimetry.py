"""Per-order Jones and Mueller matrices from one solve's amplitudes (issue 47, item 1).

Basis. Every wave of harmonic (m, n) shares its tangential wave vector k_t, and with it
s-hat = z-hat x k_t / |k_t| (rcwa/cpp/stack.cpp, polarization_basis; at k_t = 0 the plane
of incidence's). A wave's Jones vector is (E_s, E_p) with E_p along p-hat = k-hat x s-hat,
so (s-hat, p-hat, k-hat) is right-handed for each wave (incident, reflected, transmitted)
along its own direction of travel. The core measures p waves by h = Z0 H along s-hat, which
is E_p = -h / n in this basis (n the medium's index).

Normalisation. The matrices are power-normalised: J[out, in] scaled by the square root of
the ratio of the outgoing and incoming waves' power per unit amplitude through z = const
(n cos(theta) for both s and p in E terms), so that an order's efficiency for s incidence is
|J_ss|^2 + |J_ps|^2 and for p incidence |J_sp|^2 + |J_pp|^2 [Born 1999, Sec. 1.5.3;
Moharam 1995a, Eqs. 15-16 for the efficiencies].

Stokes vectors (I, Q, U, V) of a Jones vector (E_s, E_p): I = |E_s|^2 + |E_p|^2,
Q = |E_s|^2 - |E_p|^2, U = 2 Re(E_s E_p*), V = 2 Im(E_s E_p*). The Mueller matrix is
M = A (J kron J*) A^-1 [Chipman 2018], with A mapping the coherency vector
(E_s E_s*, E_s E_p*, E_p E_s*, E_p E_p*) to (I, Q, U, V); its M00 is the order's
unpolarized efficiency, (|J|_F)^2 / 2.
"""

from __future__ import annotations

import math

import numpy as np

from rcwa.result import OrderResult

POLARIMETRY_CONVENTION = (
    "jones_R/T: 2 x 2 complex [re, im], rows outgoing (s, p), columns incident (s, p); s-hat = z-hat x k_t / |k_t|, "
    "p-hat = k-hat x s-hat for each wave along its own direction; power-normalised (an order's efficiency for s "
    "incidence is |J_ss|^2 + |J_ps|^2). mueller_R/T: 4 x 4 on Stokes (I, Q, U, V) with Q = |E_s|^2 - |E_p|^2, "
    "U = 2 Re(E_s E_p*), V = 2 Im(E_s E_p*); M00 is the unpolarized efficiency"
)

# Coherency vector (E_s E_s*, E_s E_p*, E_p E_s*, E_p E_p*) -> Stokes (I, Q, U, V).
STOKES_FROM_COHERENCY = np.array([[1, 0, 0, 1], [1, 0, 0, -1], [0, 1, 1, 0], [0, -1j, 1j, 0]])
_COHERENCY_FROM_STOKES = np.linalg.inv(STOKES_FROM_COHERENCY)


def jones_matrices(order: OrderResult) -> dict[str, np.ndarray | None]:
    """The order's power-normalised Jones matrices ``{"R": J_R, "T": J_T}`` (2 x 2 complex,
    rows the outgoing s and p, columns the incident s and p; module docstring), None for a
    side on which it does not propagate or whose amplitudes were not solved (NaN: a single
    polarization's fast path)."""
    n1, n3, cos_in = order.media
    a = order.amplitudes
    out: dict[str, np.ndarray | None] = {"R": None, "T": None}
    if order.propagating_R and order.direction_R is not None and cos_in > 0:
        scale = math.sqrt(math.cos(math.radians(order.direction_R[0])) / cos_in)
        out["R"] = scale * np.array([[a["r_s_from_s"], -n1 * a["r_s_from_p"]],
                                     [-a["r_p_from_s"] / n1, a["r_p_from_p"]]], complex)
    if order.propagating_T and order.direction_T is not None and cos_in > 0 and math.isfinite(n3):
        scale = math.sqrt(n3 * math.cos(math.radians(order.direction_T[0])) / (n1 * cos_in))
        out["T"] = scale * np.array([[a["t_s_from_s"], -n1 * a["t_s_from_p"]],
                                     [-a["t_p_from_s"] / n3, n1 * a["t_p_from_p"] / n3]], complex)
    return {side: (j if j is not None and np.all(np.isfinite(j)) else None) for side, j in out.items()}


def mueller_from_jones(jones: np.ndarray) -> np.ndarray:
    """The 4 x 4 Mueller matrix of a 2 x 2 Jones matrix, M = A (J kron J*) A^-1 (module docstring)."""
    m = STOKES_FROM_COHERENCY @ np.kron(jones, np.conj(jones)) @ _COHERENCY_FROM_STOKES
    return np.real_if_close(m, tol=1e6).real


def coherency_eigenvalues(mueller: np.ndarray) -> np.ndarray:
    """Eigenvalues of the Hermitian coherency matrix of a Mueller matrix, ascending [Cloude 1986]:
    all >= 0 (to round-off) is the test that the matrix is physically realisable; one
    non-zero eigenvalue is a pure (Jones-derived) element."""
    pauli = [np.eye(2), np.array([[1, 0], [0, -1]]), np.array([[0, 1], [1, 0]]), np.array([[0, -1j], [1j, 0]])]
    h = sum(mueller[i, j] * np.kron(pauli[i], np.conj(pauli[j])) for i in range(4) for j in range(4)) / 4.0
    return np.linalg.eigvalsh(0.5 * (h + h.conj().T))


def order_polarimetry(order: OrderResult) -> dict[str, list | None]:
    """``jones_R``, ``jones_T`` (complex entries as [re, im]) and ``mueller_R``, ``mueller_T``
    (4 x 4) of one order, for ``rcwa solve --json``; None where jones_matrices gives None."""
    out: dict[str, list | None] = {}
    for side, jones in jones_matrices(order).items():
        out[f"jones_{side}"] = None if jones is None else [[[z.real, z.imag] for z in row] for row in jones.tolist()]
        out[f"mueller_{side}"] = None if jones is None else mueller_from_jones(jones).tolist()
    return out

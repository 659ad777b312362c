"""Plain-text tables for the terminal."""

from __future__ import annotations

from rcwa.result import SolveResult


def solve_table(result: SolveResult) -> str:
    """A readable table of one solve's propagating orders and totals."""
    dims = "x".join(str(n) for n in result.orders_retained)
    lines = [
        f"{result.structure}: {result.wavelength_nm:g} nm, theta {result.theta_deg:g} deg, phi {result.phi_deg:g} deg, "
        f"{result.pol}, {dims} harmonics, {result.factorization} factorization",
        f"{'m':>4} {'n':>4} {'R':>10} {'T':>10}   {'reflected to (theta, phi)':<26} {'transmitted to (theta, phi)'}",
    ]
    for o in result.orders:
        to_r = f"({o.direction_R[0]:6.2f}, {o.direction_R[1]:7.2f})" if o.direction_R else "-"
        to_t = f"({o.direction_T[0]:6.2f}, {o.direction_T[1]:7.2f})" if o.direction_T else "-"
        lines.append(f"{o.m:>4} {o.n:>4} {o.R:>10.6f} {o.T:>10.6f}   {to_r:<26} {to_t}")
    lines.append(f"total R {result.R_total:.6f}   T {result.T_total:.6f}   absorbed {result.absorption:.6f}")
    return "\n".join(lines)

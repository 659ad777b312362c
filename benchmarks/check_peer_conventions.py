"""Check, against independent references, how each peer's conventions map onto ours.

Runs in ``.venv-bench`` next to ``peer_runner.py`` (it imports that module, nothing from the
project)::

    .venv-bench/bin/python benchmarks/check_peer_conventions.py

What it checks, for each peer, through the very functions ``peer_runner`` times:

1. **s/p labels, theta, lossy-index sign, layer order** -- a uniform metal film
   (n = 0.2 + 3.4i, 30 nm) on glass, the same over a second film, and an opaque metal
   substrate, at theta = 50 deg, phi = 30 deg, against
   the Airy/Fresnel formulas written in our convention (exp(-i omega t), Im n > 0). A wrong
   s/p label swaps Rs and Rp (they differ by ~0.1 here), a wrong sign of k turns the film
   into a gain medium, a wrong theta moves everything.
2. **order index and mirror orientation in x** -- an asymmetric, partly lossy lamellar
   grating at oblique incidence, s polarization, against a small independent 1D TE RCWA
   written here directly in our convention (k_x,m = k_x,inc - m K, eps_{p-m} Toeplitz).
   An oblique angle makes order m and -m differ, an asymmetric cell makes the structure
   and its mirror image differ; the check prints the error of the mapping used and of the
   alternatives, so it is visible that the test can tell them apart.
3. **the same in y, and the 2D raster layout** -- the peer's 2D solver with a grating
   that varies along y only, incidence at phi = 90 deg, against the same 1D reference
   rotated by 90 deg about z (x' = y, y' = -x: s stays s, order n becomes m').
4. **energy**: R + T = 1 for a lossless 1D conical case and the 2D pillar case, both pols.
5. **the whole mapping at once** -- meent against grcwa on an L-shaped cell (no mirror
   symmetry) in conical incidence, s and p: two codes with different time conventions, z
   directions, order signs and raster layouts agree only if every mapping is right.

Exit status 0 when every check passes.
"""

from __future__ import annotations

import os
import sys
from typing import Any

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import peer_runner as pr  # noqa: E402  (sets the single-thread environment first)

# isort: split
import numpy as np  # noqa: E402

TOL_UNIFORM = 1e-9  # uniform stacks: both peers are exact up to round-off
TOL_GRATING = {"meent": 1e-8, "grcwa": 2e-3}  # grcwa: DFT of a sampled grid, not exact coefficients
TOL_ENERGY = 1e-9

METAL = {"n": 0.2, "k": 3.4}


# --------------------------------------------------------------------------------------------
# References in our convention
# --------------------------------------------------------------------------------------------


def kz_branch(z2):
    """sqrt with Im >= 0 (Re >= 0 when Im == 0): the project's outgoing branch."""
    r = np.sqrt(np.asarray(z2, dtype=complex))
    return np.where((r.imag < 0) | ((r.imag == 0) & (r.real < 0)), -r, r)


def airy_film(n1, n2, n3, d_over_lambda, kt):
    """R_s, R_p, T_s, T_p of one film n2 (thickness d) between n1 (incidence) and n3."""
    e1, e2, e3 = n1 * n1, n2 * n2, n3 * n3
    k1, k2, k3 = (kz_branch(e - kt * kt) for e in (e1, e2, e3))
    ph = np.exp(2j * np.pi * k2 * d_over_lambda)  # exp(i kz2 d), decays for Im kz2 > 0
    out = {}
    for pol in ("s", "p"):
        if pol == "s":
            r12, r23 = (k1 - k2) / (k1 + k2), (k2 - k3) / (k2 + k3)
            t12, t23 = 2 * k1 / (k1 + k2), 2 * k2 / (k2 + k3)
            flux_in, flux_out = k1.real, k3.real
        else:  # magnetic-field amplitudes
            r12, r23 = (e2 * k1 - e1 * k2) / (e2 * k1 + e1 * k2), (e3 * k2 - e2 * k3) / (e3 * k2 + e2 * k3)
            t12, t23 = 2 * e2 * k1 / (e2 * k1 + e1 * k2), 2 * e3 * k2 / (e3 * k2 + e2 * k3)
            flux_in, flux_out = (k1 / e1).real, (k3 / e3).real
        den = 1 + r12 * r23 * ph * ph
        r = (r12 + r23 * ph * ph) / den
        t = t12 * t23 * ph / den
        out["R_" + pol] = float(abs(r) ** 2)
        out["T_" + pol] = float(abs(t) ** 2 * flux_out / flux_in)
    return out


def stack_reflectance(indices, thicknesses_over_lambda, kt):
    """R_s, R_p of a multilayer: indices[0] incidence medium, indices[-1] substrate, films
    in between listed from the incidence side (thicknesses in wavelengths); Airy recursion."""
    eps = [n * n for n in indices]
    kz = [kz_branch(e - kt * kt) for e in eps]
    out = {}

    def r_if(i, j, pol):
        if pol == "s":
            return (kz[i] - kz[j]) / (kz[i] + kz[j])
        return (eps[j] * kz[i] - eps[i] * kz[j]) / (eps[j] * kz[i] + eps[i] * kz[j])

    for pol in ("s", "p"):
        r = r_if(len(eps) - 2, len(eps) - 1, pol)
        for j in range(len(eps) - 2, 0, -1):  # film j, from the bottom up
            ph2 = np.exp(4j * np.pi * kz[j] * thicknesses_over_lambda[j - 1])
            r = (r_if(j - 1, j, pol) + r * ph2) / (1 + r_if(j - 1, j, pol) * r * ph2)
        out["R_" + pol] = float(abs(r) ** 2)
    return out


def fourier_coefficients(segments, period, q):
    """eps_q = (1/Lambda) int eps(x) exp(-i q K x) dx for piecewise-constant eps."""
    K = 2 * np.pi / period
    out = np.zeros(len(q), dtype=complex)
    for (a, b, eps) in segments:
        for i, qq in enumerate(q):
            if qq == 0:
                out[i] += eps * (b - a) / period
            else:
                out[i] += eps * (np.exp(-1j * qq * K * b) - np.exp(-1j * qq * K * a)) / (-1j * qq * K * period)
    return out


def te_reference(segments, period, thickness, wavelength, theta, n_sup, n_sub, N):
    """1D TE (E along the grooves) RCWA, planar incidence (phi = 0), in OUR convention.

    exp(-i omega t); z into the superstrate; incident wave exp(i (kx0 x - kz0 z));
    E_y = sum_m S_m(z) exp(i kx_m x) with kx_m = kx0 - m lambda/Lambda (normalized by k0),
    so (eps E)_m = sum_p eps_{p-m} S_p. One layer, solved with bounded exponentials.
    Returns R[m], T[m] for m = -N..N.
    """
    m = np.arange(-N, N + 1)
    M = len(m)
    kx = n_sup * np.sin(theta) - m * wavelength / period
    q_idx = m[None, :] - m[:, None]  # p - m
    coeffs = fourier_coefficients(segments, period, np.arange(-2 * N, 2 * N + 1))
    E = coeffs[q_idx + 2 * N]
    A = np.diag(kx * kx) - E
    lam, W = np.linalg.eig(A)
    q = np.sqrt(lam.astype(complex))
    q = np.where(q.real < 0, -q, q)
    d = 2 * np.pi * thickness / wavelength
    X = np.diag(np.exp(-q * d))
    Q = np.diag(q)
    kz1 = kz_branch(n_sup ** 2 - kx * kx)
    kz3 = kz_branch(n_sub ** 2 - kx * kx)
    I = np.eye(M)
    Z = np.zeros((M, M))
    delta = (m == 0).astype(complex)
    WQ = W @ Q
    lhs = np.block([
        [I, Z, -W, -W @ X],
        [1j * np.diag(kz1), Z, -WQ, WQ @ X],
        [Z, I, -W @ X, -W],
        [Z, -1j * np.diag(kz3), -WQ @ X, WQ],
    ])
    rhs = np.concatenate([-delta, 1j * kz1[M // 2] * delta, np.zeros(M), np.zeros(M)])
    sol = np.linalg.solve(lhs, rhs)
    r, t = sol[:M], sol[M:2 * M]
    k0z = kz1[M // 2].real
    return m, np.abs(r) ** 2 * kz1.real / k0z, np.abs(t) ** 2 * kz3.real / k0z


# --------------------------------------------------------------------------------------------
# Checks
# --------------------------------------------------------------------------------------------

FAILURES: list[str] = []


def report(label: str, err: float, tol: float, extra: str = "") -> None:
    ok = err <= tol
    print(f"  [{'ok' if ok else 'FAIL'}] {label}: max |diff| = {err:.2e} (tol {tol:.1e}) {extra}")
    if not ok:
        FAILURES.append(label)


def solve(peer: str, data: dict) -> tuple[pr.Case, dict]:
    case = pr.parse_case(data)
    raster, _ = pr.prepare(case, peer)
    eff = (pr.solve_meent if peer == "meent" else pr.solve_grcwa)(case, raster)
    return case, eff


def check_uniform(peer: str) -> None:
    theta, phi, wl = 50.0, 30.0, 600.0
    kt = np.sin(np.radians(theta))
    film: dict[str, Any] = {"name": "film", "wavelength_nm": wl, "theta_deg": theta, "phi_deg": phi, "orders": [3],
            "structure": {"period": [1.0], "superstrate": {"n": 1.0, "k": 0}, "substrate": {"n": 1.5, "k": 0},
                          "layers": [{"thickness": 0.03, "material": METAL, "shapes": []}]}}
    _, eff = solve(peer, film)
    ref = airy_film(1.0, complex(0.2, 3.4), 1.5, 0.03 / 0.6, kt)
    got = {k: eff[k][0, 1] for k in ref}
    err = max(abs(got[k] - ref[k]) for k in ref)
    report(f"{peer}: 30 nm metal film, theta=50 phi=30, Rs/Rp/Ts/Tp vs Airy", err, TOL_UNIFORM,
           f"(ref Rs={ref['R_s']:.4f} Rp={ref['R_p']:.4f} Ts={ref['T_s']:.4f} Tp={ref['T_p']:.4f})")
    swapped = max(abs(got["R_s"] - ref["R_p"]), abs(got["R_p"] - ref["R_s"]))
    print(f"         (s/p swapped would give {swapped:.2e}; conj(n) would give "
          f"{max(abs(v - airy_film(1.0, complex(0.2, -3.4), 1.5, 0.05, kt)[k]) for k, v in got.items()):.2e})")
    two = dict(film, structure=dict(film["structure"], layers=[
        {"thickness": 0.03, "material": METAL, "shapes": []},
        {"thickness": 0.12, "material": {"n": 2.3, "k": 0.0}, "shapes": []}]))
    _, eff = solve(peer, two)
    ref = stack_reflectance([1.0, complex(0.2, 3.4), 2.3, 1.5], [0.03 / 0.6, 0.12 / 0.6], kt)
    flipped = stack_reflectance([1.0, 2.3, complex(0.2, 3.4), 1.5], [0.12 / 0.6, 0.03 / 0.6], kt)
    err = max(abs(eff["R_" + p][0, 1] - ref["R_" + p]) for p in "sp")
    report(f"{peer}: layers[0] is the top layer (metal film over n=2.3 film), Rs/Rp vs Airy", err, TOL_UNIFORM,
           f"(reversed order would give {max(abs(eff['R_' + p][0, 1] - flipped['R_' + p]) for p in 'sp'):.2e})")
    bulk = dict(film, structure=dict(film["structure"], substrate=METAL,
                                     layers=[{"thickness": 0.1, "material": {"n": 1.0, "k": 0}, "shapes": []}]))
    _, eff = solve(peer, bulk)
    ref = airy_film(1.0, 1.0, complex(0.2, 3.4), 0.1 / 0.6, kt)
    err = max(abs(eff["R_" + p][0, 1] - ref["R_" + p]) for p in "sp")
    report(f"{peer}: opaque metal substrate, Rs/Rp vs Fresnel", err, TOL_UNIFORM,
           f"(ref Rs={ref['R_s']:.4f} Rp={ref['R_p']:.4f})")


ASYM_SEGMENTS = [  # (x0, x1, index) over one period of 1 um: a strongly asymmetric cell
    (0.0, 0.15, complex(2.2, 0.0)),
    (0.15, 0.40, complex(1.6, 0.3)),
    (0.40, 1.0, complex(1.0, 0.0)),
]


def asym_case(two_d: str | None, theta: float, phi: float, N: int) -> dict:
    shapes = []
    for (a, b, n) in ASYM_SEGMENTS[:2]:
        mat = {"n": n.real, "k": n.imag}
        if two_d is None:
            shapes.append({"material": mat, "x": [a, b]})
        elif two_d == "x":
            shapes.append({"material": mat, "rect": {"center": [(a + b) / 2, 0.5], "size": [b - a, 1.0]}})
        else:  # varies along y
            shapes.append({"material": mat, "rect": {"center": [0.5, (a + b) / 2], "size": [1.0, b - a]}})
    period = [1.0] if two_d is None else [1.0, 1.0]
    orders = [2 * N + 1] if two_d is None else ([2 * N + 1, 3] if two_d == "x" else [3, 2 * N + 1])
    return {"name": "asym", "wavelength_nm": 450.0, "theta_deg": theta, "phi_deg": phi, "orders": orders,
            "structure": {"period": period, "superstrate": {"n": 1.0, "k": 0}, "substrate": {"n": 1.45, "k": 0},
                          "layers": [{"thickness": 0.35, "material": {"n": 1.0, "k": 0}, "shapes": shapes}]}}


def check_orders(peer: str) -> None:
    N, theta = 10, 25.0
    m, Rref, Tref = te_reference([(a, b, n * n) for a, b, n in ASYM_SEGMENTS], 1.0, 0.35, 0.45,
                                 np.radians(theta), 1.0, 1.45, N)
    for label, two_d, phi in (("1D solver, grating along x", None, 0.0),
                              ("2D solver, grating along x", "x", 0.0),
                              ("2D solver, grating along y (phi=90, rotated reference)", "y", 90.0)):
        case, eff = solve(peer, asym_case(two_d, theta, phi, N))
        if two_d == "y":
            R, T = eff["R_s"][:, 1], eff["T_s"][:, 1]  # column m = 0, rows n = -N..N
        else:
            R, T = eff["R_s"][eff["R_s"].shape[0] // 2, :], eff["T_s"][eff["T_s"].shape[0] // 2, :]
        err = max(np.max(np.abs(R - Rref)), np.max(np.abs(T - Tref)))
        # the alternatives the check must be able to exclude:
        flipped = max(np.max(np.abs(R[::-1] - Rref)), np.max(np.abs(T[::-1] - Tref)))  # m -> -m
        _, Rmir, Tmir = te_reference([(1 - b, 1 - a, n * n) for a, b, n in ASYM_SEGMENTS], 1.0, 0.35, 0.45,
                                     np.radians(theta), 1.0, 1.45, N)
        mirrored = max(np.max(np.abs(R - Rmir)), np.max(np.abs(T - Tmir)))  # structure x -> -x
        report(f"{peer}: {label}, s, theta={theta:g}, asymmetric lossy cell", err, TOL_GRATING[peer],
               f"(m->-m would give {flipped:.2e}, mirrored cell {mirrored:.2e})")
        # the grating equation: orders listed as reflected-propagating are exactly |kx_m| < 1
        kx = np.sin(np.radians(theta)) - m * 0.45
        evan = np.abs(kx) >= 1.0
        leak = float(np.max(R[evan])) if np.any(evan) else 0.0
        report(f"{peer}: {label}, R of orders with |kx - m lambda/Lambda| > n_sup is zero", leak, 1e-12,
               f"(propagating in air: m = {m[~evan].min()}..{m[~evan].max()})")


def check_energy(peer: str) -> None:
    conical = {"name": "conical", "wavelength_nm": 600.0, "theta_deg": 30.0, "phi_deg": 30.0, "orders": [41],
               "structure": {"period": [1.0], "superstrate": {"n": 1.0, "k": 0}, "substrate": {"n": 1.5, "k": 0},
                             "layers": [{"thickness": 0.5, "material": {"n": 1.0, "k": 0},
                                         "shapes": [{"material": {"n": 1.5, "k": 0}, "x": [0.0, 0.5]}]}]}}
    pillars = {"name": "pillars", "wavelength_nm": 600.0, "theta_deg": 30.0, "phi_deg": 30.0, "orders": [7, 7],
               "structure": {"period": [1.0, 1.0], "superstrate": {"n": 1.0, "k": 0},
                             "substrate": {"n": 1.5, "k": 0},
                             "layers": [{"thickness": 0.3, "material": {"n": 1.0, "k": 0},
                                         "shapes": [{"material": {"n": 2.0, "k": 0},
                                                     "rect": {"center": [0.5, 0.5], "size": [0.5, 0.5]}}]}]}}
    for data in (conical, pillars):
        case, eff = solve(peer, data)
        for pol in "sp":
            total = float(np.sum(eff["R_" + pol]) + np.sum(eff["T_" + pol]))
            report(f"{peer}: {case.name}, {pol}: R + T = 1", abs(total - 1.0), TOL_ENERGY, f"(sum {total:.12f})")


TOL_CROSS = 1.5e-2  # meent ([Li 1997]) vs grcwa (Laurent), 9 x 9 orders, n = 1.4: truncation, not mapping


def check_cross_2d() -> None:
    """meent vs grcwa on an L-shaped (mirror-asymmetric in x and y) cell, conical, s and p.

    The two codes share nothing (time convention, z direction, order sign, raster layout all
    differ), so agreement after mapping, and disagreement under every wrong flip of m or n,
    tests the whole mapping jointly, p polarization and phi included.
    """
    data = {"name": "L-shape", "wavelength_nm": 550.0, "theta_deg": 35.0, "phi_deg": 25.0, "orders": [9, 9],
            "structure": {"period": [1.0, 0.8], "superstrate": {"n": 1.0, "k": 0}, "substrate": {"n": 1.5, "k": 0},
                          "layers": [{"thickness": 0.4, "material": {"n": 1.0, "k": 0}, "shapes": [
                              {"material": {"n": 1.4, "k": 0}, "rect": {"center": [0.3, 0.2], "size": [0.4, 0.2]}},
                              {"material": {"n": 1.4, "k": 0}, "rect": {"center": [0.2, 0.45], "size": [0.2, 0.3]}},
                          ]}]}}
    _, a = solve("meent", data)
    _, b = solve("grcwa", data)
    keys = ("R_s", "R_p", "T_s", "T_p")

    def diff(flip_m: bool, flip_n: bool) -> float:
        sl = (slice(None, None, -1 if flip_n else 1), slice(None, None, -1 if flip_m else 1))
        return max(float(np.max(np.abs(a[k] - b[k][sl]))) for k in keys)

    report("meent vs grcwa: L-shaped 2D cell, theta=35 phi=25, s and p, all orders", diff(False, False),
           TOL_CROSS, f"(flip m: {diff(True, False):.2e}, flip n: {diff(False, True):.2e}, "
           f"both: {diff(True, True):.2e})")
    print(f"         (largest efficiency in the comparison: {max(float(np.max(a[k])) for k in keys):.3f})")


def main() -> int:
    for peer in pr.PEERS:
        print(f"{peer} {pr.meent_version() if peer == 'meent' else pr.grcwa_version()}")
        check_uniform(peer)
        check_orders(peer)
        check_energy(peer)
    check_cross_2d()
    if FAILURES:
        print(f"{len(FAILURES)} check(s) failed: " + "; ".join(FAILURES))
        return 1
    print("all convention checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())

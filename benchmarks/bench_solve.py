"""Side-by-side benchmark of one RCWA solve: our solver against open-source peers.

Runs in the project's ``.venv``; the peers (meent, grcwa, fmmax) run in their own ``.venv-bench``
through ``peer_runner.py --serve`` in a subprocess per case and peer (warmed up once, then
one timed round per request), so their pinned numpy never meets ours::

    bash benchmarks/setup_peers.sh           # once (``make bench`` does it)
    .venv/bin/python benchmarks/bench_solve.py [--out build/bench/rcwa_solve.json]
                     [--repeats 3] [--rounds 2] [--peers meent,grcwa,fmmax]
                     [--cases p2c,p2k,cd0,cd30,g9,g15 (default; also a1,a2,b)] [--factorizations li,nv]
                     [--no-reference] [--peers-only | --no-peers] [--base SITE_DIR]
                     [--no-sectors | --sectors-only]

Cases p2c / p2k: P2 ([Moharam 1995a, Fig. 2]) in classical (phi 0) and conical (phi 30)
mount; cd0 / cd30: the CD at phi 0 and 30; g9 / g15: gold2d at 9 x 9 and 15 x 15 orders
off its mirror planes (theta 20, phi 30). ``--base DIR`` times another build of our
solver in the same rounds (a subprocess importing rcwa from DIR first), e.g. the base
commit: ``git worktree add /tmp/base HEAD; pip wheel --no-build-isolation --no-deps
/tmp/base -w /tmp/wheel; pip install --no-deps --target /tmp/base_site /tmp/wheel/*.whl``.
A second table prints ours for s, p and s+p against the eigen-solve floor (eigen_floor)
and the base build. A third prints gold2d (rcwa/structures/gold2d.toml) at 9 x 9 and 15 x 15
orders, at normal incidence and in its xz mirror plane, solved in mirror-symmetry sectors
(rcwa/cpp/sectors.hpp) and by the general path, and estimates the gold2d paper-preset
table's time with and without them from sampled sweeps (``--no-sectors`` skips it,
``--sectors-only`` runs only it).

Cases (each is one JSON-able dict; ``"structure"`` is exactly the project's structure-file
format as a dict; lengths in micrometres, wavelength in nm, angles in degrees)::

    {"name": ..., "wavelength_nm": 600, "theta_deg": 30, "phi_deg": 30, "orders": [61] | [11, 11],
     "structure": {"period": [1.0] | [1.0, 1.0], "superstrate": {"n": 1, "k": 0},
                   "substrate": {"n": 1.5, "k": 0},
                   "layers": [{"thickness": 0.5, "material": {"n": 1, "k": 0},
                               "shapes": [{"material": {...}, "x": [0.0, 0.5]}]}]}}

2D shapes are ``{"material": {...}, "rect": {"center": [cx, cy], "size": [sx, sy]}}``;
layers are listed from the superstrate down; uniform layers have no shapes.

What is measured, per case, all on ONE thread (OMP/OPENBLAS/MKL_NUM_THREADS=1 for us and
for the peers):

* ours: ``rcwa.solve(structure, wl, theta, phi, orders=..., pol="s")`` and the same with
  ``pol="p"`` and ``pol="unpolarized"`` (s+p), interleaved, in CPU time
  (``time.process_time``: the machine's background load does not count), each the
  median of all rounds' repeats after one warm-up call, with every
  factorization in ``OUR_FACTORIZATIONS`` (the default, and in 2D also [Li 1997], which is
  what meent uses). The structure is built once, outside the timing (the peers'
  rasterization is outside theirs too). "ours s+p" is one unpolarized call; a 1D
  classical-mount s or p call solves only that polarization (rcwa/cpp/polarized.hpp).
* each peer: the median CPU time (``time.process_time`` in its process, one BLAS and XLA
  thread) to get the efficiencies of s, of p, and of both, each by the peer's fastest
  route (meent: its TE-only / TM-only solver in classical mount, else one solve for both;
  grcwa and fmmax: one excitation per polarization; s+p: the cheaper of one
  two-polarization solve and an s plus a p solve), model and Fourier matrices included.
* ``--rounds`` interleave ours and the peers; each keeps its best per-round median, so a
  burst of background load does not decide the ratio.
* ratio = peer time / ours, per polarization (> 1: we are faster; issue 17's goal: >= 2).
* floor: the eigen-decompositions the case needs, timed alone in the same rounds with the
  best LAPACK routine that applies (floor_jobs); ours / floor is issue 17's second goal
  (<= 1.3). The last table (print_summary) puts these together.
* max |dDE|: the largest difference of an efficiency (R or T, s or p) over the orders either
  side lists (a missing order counts as 0). Over an absorbing substrate T is not a
  plane-flux efficiency (ours reports T = 0 there), so only R is compared per order and the
  total power into the substrate separately (JSON only).
* err vs ref: the same against meent at a much higher truncation (3x the orders in 1D,
  21 x 21 in 2D), so that truncation error and disagreement can be told apart.

Conventions (``workbench/core/conventions.py``): order m has k_x,m = k_x,inc - m 2 pi/Lambda_x;
the incident wave travels toward -z with tangential k0 n_sup (sin t cos p, sin t sin p);
s = TE (E perpendicular to the plane of incidence). peer_runner maps each peer onto them;
``check_peer_conventions.py`` proves the mapping against independent references.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
             "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import copy  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PEER_RUNNER = HERE / "peer_runner.py"
PEER_PYTHON = ROOT / ".venv-bench" / "bin" / "python"
DEFAULT_OUT = ROOT / "build" / "bench" / "rcwa_solve.json"
ALL_PEERS = ("meent", "grcwa", "fmmax")

AIR = {"n": 1.0, "k": 0.0}
GLASS = {"n": 1.5, "k": 0.0}
GOLD_600NM = {"n": 0.2, "k": 3.4}  # fixed gold-like index at 600 nm (no dispersion needed here)

P2_BASE = {
    "wavelength_nm": 1000.0, "theta_deg": 10.0, "orders": [61],
    "structure": {
        "period": [10.0], "superstrate": AIR, "substrate": {"n": 2.04, "k": 0.0},
        "layers": [{"thickness": 1.0, "material": AIR, "shapes": [{"material": {"n": 2.04, "k": 0.0}, "x": [0.0, 3.0]}]}],
    },
}
POLYCARBONATE_633NM = {"n": 1.5805, "k": 0.0}
ALUMINIUM_633NM = {"n": 1.3406, "k": 7.3015}
CD_BASE = {
    "wavelength_nm": 633.0, "theta_deg": 20.0, "orders": [61],
    "structure": {
        "period": [1.6], "superstrate": POLYCARBONATE_633NM, "substrate": ALUMINIUM_633NM,
        "layers": [{"thickness": 0.11, "material": POLYCARBONATE_633NM,
                    "shapes": [{"material": ALUMINIUM_633NM, "x": [0.5, 1.1]}]}],
    },
}

GOLD2D_BASE = {
    "wavelength_nm": 600.0, "theta_deg": 20.0, "phi_deg": 30.0,
    "structure": {
        "period": [1.0, 1.0], "superstrate": AIR, "substrate": AIR,
        "layers": [{"thickness": 1.0, "material": AIR,
                    "shapes": [{"material": GOLD_600NM, "rect": {"center": [0.5, 0.5], "size": [0.5, 0.5]}}]}],
    },
}
# The cases issue 17 asks for (the default of --cases); a1, a2 and b can be asked for.
DEFAULT_CASES = ("p2c", "p2k", "cd0", "cd30", "g9", "g15")

CASES: dict[str, dict] = {
    "a1": {
        "name": "lamellar_dielectric_conical",
        "wavelength_nm": 600.0, "theta_deg": 30.0, "phi_deg": 30.0, "orders": [61],
        "structure": {
            "period": [1.0], "superstrate": AIR, "substrate": GLASS,
            "layers": [{"thickness": 0.5, "material": AIR,
                        "shapes": [{"material": GLASS, "x": [0.0, 0.5]}]}],
        },
    },
    "a2": {
        "name": "lamellar_metal_conical",
        "wavelength_nm": 600.0, "theta_deg": 30.0, "phi_deg": 30.0, "orders": [61],
        "structure": {
            "period": [1.0], "superstrate": AIR, "substrate": GOLD_600NM,
            "layers": [{"thickness": 0.1, "material": AIR,
                        "shapes": [{"material": GOLD_600NM, "x": [0.0, 0.5]}]}],
        },
    },
    # P2: the dielectric binary grating of [Moharam 1995a, Fig. 2] (period 10 lambda, n = 2.04,
    # fill 0.3, 10 deg), one wavelength deep. The substrate index is given as 2.04 + 0j
    # (k = 0.0): meent takes a wrong kz branch in classical mount for 2.04 - 0j (issue 17).
    "p2c": {"name": "P2_classical", **P2_BASE, "phi_deg": 0.0},
    "p2k": {"name": "P2_conical", **P2_BASE, "phi_deg": 30.0},
    # The CD of rcwa/structures/cd.toml with its materials' indices at 633 nm.
    "cd0": {"name": "cd_phi0", **CD_BASE, "phi_deg": 0.0},
    "cd30": {"name": "cd_phi30", **CD_BASE, "phi_deg": 30.0},
    # gold2d (rcwa/structures/gold2d.toml: 0.5 x 0.5 x 1 um gold blocks, period 1 um, in air)
    # with gold at a fixed index, in a direction off its mirror planes (the paper table's
    # common case: no symmetry sectors).
    "g9": {"name": "gold2d_9x9", **GOLD2D_BASE, "orders": [9, 9]},
    "g15": {"name": "gold2d_15x15", **GOLD2D_BASE, "orders": [15, 15]},
    "b": {
        "name": "square_pillars_2d",
        "wavelength_nm": 600.0, "theta_deg": 30.0, "phi_deg": 30.0, "orders": [11, 11],
        "structure": {
            "period": [1.0, 1.0], "superstrate": AIR, "substrate": GLASS,
            "layers": [{"thickness": 0.3, "material": AIR,
                        "shapes": [{"material": {"n": 2.0, "k": 0.0},
                                    "rect": {"center": [0.5, 0.5], "size": [0.5, 0.5]}}]}],
        },
    },
}

# Factorization rules our solver is timed with, per dimension: "auto" is the default a user
# gets ([Li 1996] in 1D; in 2D [Li 1997] for cells made of rectangles, else the normal vector
# method [Schuster 2007]). ``--factorizations li,nv`` adds others; a rule that resolves to one already
# timed is dropped.
OUR_FACTORIZATIONS = {1: ("auto",), 2: ("auto",)}
OUR_FORMULATION = {
    (1, "li"): "Moharam 1995 conical + Li 1996 inverse rule (eps_x), ETM stack",
    (1, "nv"): "Moharam 1995 conical + Li 1996 inverse rule (eps_x), ETM stack",
    (1, "laurent"): "Moharam 1995 conical + Laurent rule, ETM stack",
    (2, "li"): "Li 1997 crossed-grating rules (exact for rectangles), ETM stack",
    (2, "nv"): "Schuster 2007 normal vector method, ETM stack",
    (2, "laurent"): "Laurent rule, ETM stack",
}
KEYS = ("R_s", "R_p", "T_s", "T_p")


class BenchError(RuntimeError):
    """A benchmark step that cannot go on; the message says what to do."""


# --------------------------------------------------------------------------------------------
# Our solver
# --------------------------------------------------------------------------------------------


def import_rcwa():
    """Import the project's solver (in-tree when not installed) or raise :class:`BenchError`."""
    try:
        import rcwa  # noqa: F401
    except ImportError:
        if str(ROOT) not in sys.path:
            sys.path.append(str(ROOT))
        try:
            import rcwa  # noqa: F401
        except ImportError as exc:
            raise BenchError(f"cannot import rcwa ({exc}); build it first (make install)") from exc
    import rcwa

    if not hasattr(rcwa, "solve") or not hasattr(rcwa, "Structure"):
        raise BenchError("rcwa has no solve()/Structure yet (the C++ core is not built or not landed)")
    return rcwa


def orders_arg(case: dict):
    o = case["orders"]
    return int(o[0]) if len(o) == 1 else (int(o[0]), int(o[1]))


def substrate_is_lossy(case: dict) -> bool:
    sub = case["structure"]["substrate"]
    return isinstance(sub, dict) and float(sub.get("k", 0.0)) != 0.0


def our_efficiencies(res_s, res_p) -> dict[tuple[int, int], dict[str, float]]:
    """(m, n) -> {R_s, R_p, T_s, T_p} of the listed orders: s values from the pol="s"
    result, p values from the pol="p" one (a single-polarization solve leaves the other NaN)."""
    out: dict[tuple[int, int], dict[str, float]] = {}
    for pol, res in (("s", res_s), ("p", res_p)):
        for o in res.orders:
            entry = out.setdefault((int(o.m), int(getattr(o, "n", 0) or 0)), {k: 0.0 for k in KEYS})
            for k in ("R_", "T_"):
                entry[k + pol] = float(getattr(o, k + pol)) if hasattr(o, k + pol) else float(getattr(o, k[0]))
    return out


def cpu_time() -> float:
    """CPU time of this process (one BLAS thread): background load on the machine does not count."""
    return time.process_time()


POLS = (("s", "s"), ("p", "p"), ("both", "unpolarized"))


def time_ours(rcwa, structure, case: dict, factorization: str, repeats: int) -> dict:
    """One round: a warm-up, then ``repeats`` interleaved timed calls for pol s, p and
    unpolarized (s+p), each in CPU seconds."""
    args = (structure, case["wavelength_nm"], case["theta_deg"], case["phi_deg"])
    kw = {"orders": orders_arg(case)}
    if factorization != "auto":
        kw["factorization"] = factorization
    timings: dict[str, list[float]] = {key: [] for key, _ in POLS}
    results = {key: rcwa.solve(*args, pol=pol, **kw) for key, pol in POLS}  # warm-up
    for _ in range(repeats):
        for key, pol in POLS:
            t0 = cpu_time()
            results[key] = rcwa.solve(*args, pol=pol, **kw)
            timings[key].append(cpu_time() - t0)
    return {"times_s": timings["s"], "times_p": timings["p"], "times_both": timings["both"],
            "res_s": results["s"], "res_p": results["p"]}


def summarize_ours(case: dict, factorization: str, rounds: list[dict], t_build: float) -> dict:
    res = rounds[-1]["res_s"]
    kind = len(case["structure"]["period"])
    rule = str(getattr(res, "factorization", factorization))
    # The best (min) of the per-round medians, as for the peers.
    med = {key: min(statistics.median(r["times_" + key]) for r in rounds) for key, _ in POLS}
    return {
        "factorization": rule,
        "formulation": OUR_FORMULATION.get((kind, rule), rule),
        "fast_paths": {key: list(getattr(rounds[-1]["res_" + key], "fast_paths", ())) for key in ("s", "p")},
        "seconds_s": med["s"],
        "seconds_p": med["p"],
        "seconds_both_pols": med["both"],  # one pol="unpolarized" call
        "both_pols_per_call": True,
        "seconds_all_s": [t for r in rounds for t in r["times_s"]],
        "seconds_all_p": [t for r in rounds for t in r["times_p"]],
        "seconds_all_both": [t for r in rounds for t in r["times_both"]],
        "seconds_structure_build": t_build,
        "efficiencies": our_efficiencies(res, rounds[-1]["res_p"]),
        "power_into_substrate": None,
    }


REAL_TOLERANCE = 1e-13  # |Im| / max|.| below which a shifted layer matrix counts as real


def _real_by_shift(mats: list, m, period: float, centres: list[float]) -> list | None:
    """The layer matrices with the origin moved to one of ``centres`` where that makes them all
    real (a layer symmetric about that point), else None. A shift by x0 multiplies entry
    (i, j) by exp(-+i (m_i - m_j) 2 pi x0 / period), which changes no efficiency."""
    import numpy as np

    for x0 in centres:
        for sign in (1.0, -1.0):
            d = np.exp(sign * 2j * np.pi * m * x0 / period)
            shifted = [d[:, None] * a * d.conj()[None, :] for a in mats]
            if all(np.abs(a.imag).max() <= REAL_TOLERANCE * np.abs(a).max() for a in shifted):
                return [np.ascontiguousarray(a.real) for a in shifted]
    return None


def _shape_centres(case: dict) -> list[float]:
    return sorted({0.5 * (sh["x"][0] + sh["x"][1]) for lay in case["structure"]["layers"]
                   for sh in lay.get("shapes", []) if "x" in sh} | {0.0})


def floor_jobs(structure, case: dict) -> tuple[dict[str, list], dict[str, tuple[str, ...]], dict[str, str]]:
    """The eigen-decompositions a case needs, as callables, with the best LAPACK routine that
    applies (scipy), which of them each of s, p and s+p needs, and the routines' names.

    1D, per lamellar layer: TE: E - Kx^2 - Ky^2 (Hermitian when the layer is lossless: dsyevd
    when moving the origin to a stripe's centre makes it real, else zheevd; zgeev when
    lossy); TM: Exx (I - Kx E^-1 Kx) (lossless: the symmetric-definite pencil (Exx B Exx,
    Exx), dsygvd / zhegvd; lossy: zgeev). Classical mount: s needs TE, p needs TM; conical:
    both for either. 2D, per patterned layer: the 2N x 2N matrix P Q of the layer (zgeev;
    it is not Hermitian in general), which every polarization needs off the mirror planes."""
    import numpy as np
    import scipy.linalg as sla

    from rcwa.solver import prepare

    prep = prepare(structure, case["wavelength_nm"], orders_arg(case))
    theta, phi = (float(np.radians(case[k])) for k in ("theta_deg", "phi_deg"))
    n_sup = np.sqrt(prep.eps_sup.real)
    kx = n_sup * np.sin(theta) * np.cos(phi) + prep.dkx
    ky = n_sup * np.sin(theta) * np.sin(phi) + prep.dky
    # A lamellar layer by Li's inverse rule carries [[1/eps]]; its Exx is the inverse (formed
    # here outside the timed jobs, as the core forms it outside its eigen-solves).
    patterned: list[tuple[np.ndarray, ...]] = [
        (layer.matrices[0], np.linalg.inv(layer.matrices[1])) if layer.inverse_rule else layer.matrices
        for layer in prep.layers if layer.matrices]
    if len(case["structure"]["period"]) == 2:
        jobs: dict[str, list] = {"full": []}
        for E, exx, exy, eyx, eyy in patterned:
            Ei = np.linalg.inv(E)
            KxEi, KyEi = kx[:, None] * Ei, ky[:, None] * Ei
            P = np.block([[KxEi * ky[None, :], np.eye(kx.size) - KxEi * kx[None, :]],
                          [KyEi * ky[None, :] - np.eye(kx.size), -KyEi * kx[None, :]]])
            Q = np.block([[np.diag(kx * ky) - exy, eyy - np.diag(kx * kx)], [np.diag(ky * ky) - exx, eyx - np.diag(kx * ky)]])
            jobs["full"].append(lambda M=P @ Q: sla.eig(M, left=False, right=True, check_finite=False))
        full: dict[str, tuple[str, ...]] = {key: ("full",) for key in ("s", "p", "both")}
        return jobs, full, {"full": "zgeev (2N x 2N)"}
    jobs = {"te": [], "tm": []}
    names: dict[str, set[str]] = {"te": set(), "tm": set()}
    for E, Exx in patterned:
        lossless = np.allclose(E, E.conj().T, rtol=0, atol=1e-14 * np.abs(E).max())
        if lossless:
            real = _real_by_shift([E, Exx], prep.harmonics.m, float(case["structure"]["period"][0]), _shape_centres(case))
            E_, Exx_ = real if real is not None else (E, Exx)
            MA = E_ - np.diag(kx**2 + ky**2)
            B = np.eye(kx.size) - kx[:, None] * np.linalg.inv(E_) * kx[None, :]
            jobs["te"].append(lambda MA=MA: sla.eigh(MA, driver="evd", check_finite=False))
            jobs["tm"].append(lambda A=Exx_ @ B @ Exx_, Exx=Exx_: sla.eigh(A, Exx, driver="gvd", check_finite=False))
            names["te"].add("dsyevd" if real is not None else "zheevd")
            names["tm"].add("dsygvd" if real is not None else "zhegvd")
        else:
            MA = E - np.diag(kx**2 + ky**2)
            B = np.eye(kx.size) - kx[:, None] * np.linalg.inv(E) * kx[None, :]
            jobs["te"].append(lambda MA=MA: sla.eig(MA, left=False, right=True, check_finite=False))
            jobs["tm"].append(lambda M=Exx @ B: sla.eig(M, left=False, right=True, check_finite=False))
            names["te"].add("zgeev")
            names["tm"].add("zgeev")
    classical = case["phi_deg"] == 0.0
    one_pol: tuple[str, ...] = ("te", "tm")
    need = {"s": ("te",) if classical else one_pol, "p": ("tm",) if classical else one_pol, "both": one_pol}
    return jobs, need, {k: "+".join(sorted(v)) for k, v in names.items()}


def paired_floor(rcwa, structure, case: dict, jobs: dict[str, list], need: dict[str, tuple[str, ...]],
                 pairs: int) -> dict[str, float]:
    """Ours over the floor from back-to-back pairs in this process: per pair and polarization
    one ``rcwa.solve`` and at once the eigen-decompositions that polarization needs; the ratio
    of the two minima over the pairs. Each minimum is its least-disturbed run, and the pairs
    put both sides in the same seconds: this machine's speed drifts by 10-25 % from one
    moment to the next, which ratios of times measured apart (the /floor column) carry."""
    args = (structure, case["wavelength_nm"], case["theta_deg"], case["phi_deg"])
    kw = {"orders": orders_arg(case)}
    best: dict[str, list[float]] = {key: [math.inf, math.inf] for key, _ in POLS}
    for _ in range(pairs):
        for key, pol in POLS:
            t0 = cpu_time()
            rcwa.solve(*args, pol=pol, **kw)
            t1 = cpu_time()
            for group in need[key]:
                for job in jobs[group]:
                    job()
            t2 = cpu_time()
            best[key] = [min(best[key][0], t1 - t0), min(best[key][1], t2 - t1)]
    return {key: ours / floor for key, (ours, floor) in best.items()}


def floor_round(jobs: dict[str, list], repeats: int) -> dict[str, float]:
    """One round of the floor: per job group, the median CPU seconds of ``repeats`` runs after a warm-up."""
    times: dict[str, list[float]] = {key: [] for key in jobs}
    for key in jobs:
        for job in jobs[key]:
            job()
    for _ in range(repeats):
        for key, group in jobs.items():
            t0 = cpu_time()
            for job in group:
                job()
            times[key].append(cpu_time() - t0)
    return {key: statistics.median(v) for key, v in times.items()}


def eigen_floor(need: dict[str, tuple[str, ...]], rounds: list[dict[str, float]], routines: dict[str, str]) -> dict:
    """CPU seconds of the eigen-decompositions each of s, p and s+p needs: per group the best
    (min) of the per-round medians, summed over the groups that polarization needs."""
    best = {key: min(r[key] for r in rounds) for key in rounds[0]}
    out: dict = {pol: sum(best[k] for k in groups) for pol, groups in need.items()}
    out["routines"] = routines
    return out


# --------------------------------------------------------------------------------------------
# Peers
# --------------------------------------------------------------------------------------------


def peer_env() -> dict[str, str]:
    env = dict(os.environ)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
                "NUMEXPR_NUM_THREADS"):
        env[var] = "1"
    env["XLA_FLAGS"] = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"  # fmmax (JAX)
    env["JAX_PLATFORMS"] = "cpu"
    env.pop("PYTHONPATH", None)  # the peer environment must not see our packages
    return env


def check_peer_env() -> None:
    if not PEER_PYTHON.exists():
        raise BenchError(
            f"the peers' environment {PEER_PYTHON.parent.parent} is missing; create it with\n"
            f"    bash {HERE.relative_to(ROOT)}/setup_peers.sh\n"
            f"(`make bench` runs it first), or run with --no-peers to time our solver alone")


def _peer_output(out: dict) -> dict:
    out["efficiencies"] = {(o["m"], o["n"]): {k: o[k] for k in KEYS} for o in out.pop("orders")}
    return out


def run_peer(case: dict, peer: str, repeats: int) -> dict:
    """One run of peer_runner (a warm-up and ``repeats`` timed calls) in its environment."""
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as fh:
        json.dump(case, fh)
        path = fh.name
    try:
        proc = subprocess.run(
            [str(PEER_PYTHON), str(PEER_RUNNER), path, "--peer", peer, "--repeats", str(repeats)],
            capture_output=True, text=True, env=peer_env(), cwd=str(ROOT), timeout=3600)
    finally:
        os.unlink(path)
    if proc.returncode != 0:
        raise BenchError(f"peer {peer} failed on {case['name']} (exit {proc.returncode}):\n{proc.stderr.strip()}")
    return _peer_output(json.loads(proc.stdout))


class PeerServer:
    """peer_runner --serve for one case and peer: warmed up once (fmmax's jit compilation
    costs seconds), then one timed round per :meth:`round`, interleaved with ours."""

    def __init__(self, case: dict, peer: str) -> None:
        self.name, self.peer = case["name"], peer
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as fh:
            json.dump(case, fh)
            self.path = fh.name
        self.err = tempfile.TemporaryFile("w+")
        self.proc = subprocess.Popen(
            [str(PEER_PYTHON), str(PEER_RUNNER), self.path, "--peer", peer, "--serve"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.err, text=True, env=peer_env(), cwd=str(ROOT))
        self._expect("ready")

    def _expect(self, what: str) -> str:
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line or (what == "ready" and line.strip() != "ready"):
            self.err.seek(0)
            self.close()
            raise BenchError(f"peer {self.peer} failed on {self.name}:\n{self.err.read().strip()}")
        return line

    def round(self, repeats: int) -> dict:
        assert self.proc.stdin is not None
        self.proc.stdin.write(f"{repeats}\n")
        self.proc.stdin.flush()
        return _peer_output(json.loads(self._expect("round")))

    def close(self) -> None:
        if self.proc.stdin is not None and not self.proc.stdin.closed:
            self.proc.stdin.close()
        self.proc.wait(timeout=60)
        os.unlink(self.path)


def reference_case(case: dict) -> dict:
    ref = copy.deepcopy(case)
    o = case["orders"]
    ref["orders"] = [3 * (o[0] // 2) * 2 + 1] if len(o) == 1 else [max(21, x) for x in o]
    ref["name"] = case["name"] + "_reference"
    return ref


def summarize_peer(runs: list[dict]) -> dict:
    """Merge the rounds of one peer: min over rounds of the per-round medians."""
    out = dict(runs[-1])
    out["seconds_per_solve"] = min(r["seconds_per_solve"] for r in runs)
    for key in ("seconds_s", "seconds_p"):
        out[key] = min(r.get(key, r["seconds_per_solve"]) for r in runs)
    # Both polarizations by the peer's fastest route: one two-polarization solve, or two
    # single ones where those are cheaper (meent's TE-only / TM-only solver in classical mount).
    out["seconds_both_best"] = min(out["seconds_per_solve"], out["seconds_s"] + out["seconds_p"])
    out["seconds_all"] = [t for r in runs for t in r["seconds_all"]]
    out["rounds"] = len(runs)
    return out


# --------------------------------------------------------------------------------------------
# Comparison and report
# --------------------------------------------------------------------------------------------


def compared_keys(case: dict) -> tuple[str, ...]:
    """Per-order quantities compared: with an absorbing substrate T is no plane-flux
    efficiency (it depends on depth; our solver reports T = 0 there), so only R is."""
    return ("R_s", "R_p") if substrate_is_lossy(case) else KEYS


def max_diff(a: dict, b: dict, keys: tuple[str, ...] = KEYS) -> tuple[float, str]:
    """Largest |dDE| over the union of orders (a missing order counts as 0) and where."""
    worst, where = 0.0, ""
    for key in sorted(set(a) | set(b)):
        ea, eb = a.get(key, {}), b.get(key, {})
        for k in keys:
            d = abs(ea.get(k, 0.0) - eb.get(k, 0.0))
            if d > worst:
                worst, where = d, f"{k} (m={key[0]}, n={key[1]})"
    return worst, where


def formulations_match(ours_rule: str, peer_rule: str, kind: int) -> str:
    """Compare our factorization rule ("li", "nv", "laurent") with the peer's label."""
    if peer_rule == "laurent":
        return "yes (Laurent)" if ours_rule == "laurent" else "no (peer: Laurent)"
    if kind == 1:
        return "yes (Li 1996)" if (ours_rule in ("li", "nv") and peer_rule == "li1996") else "no"
    if ours_rule == "li" and peer_rule.startswith("li1997"):
        return "close (Li 1997, other nesting)" if "reversed" in peer_rule else "yes (Li 1997)"
    if ours_rule == "nv" and peer_rule.startswith("li1997"):
        return "no (ours NVM, peer Li 1997)"
    return "no"


def fmt_ms(s: float | None, width: int = 8) -> str:
    return f"{'-':>{width}s}" if s is None else f"{1e3 * s:{width}.2f}"


def fmt_e(x: float | None) -> str:
    return f"{'-':>9s}" if x is None else f"{x:9.1e}"


def print_table(rows: list[dict]) -> None:
    head = (f"{'case':28s} {'orders':>6s} {'ours':>7s} {'ours s':>8s} {'ours p':>8s} {'ours s+p':>8s} "
            f"{'peer':>6s} {'peer s+p':>8s} {'ratio':>6s} {'max|dDE|':>9s} {'ours err':>9s} "
            f"{'peer err':>9s}  formulations match")
    print(head)
    print("-" * len(head))
    for r in rows:
        ours_list = r.get("ours") or [None]
        for ours in ours_list:
            for peer in r["peers"] or [{}]:
                name = peer.get("peer", "-")
                pt = peer.get("seconds_both_best", peer.get("seconds_per_solve"))
                both = ours["seconds_both_pols"] if ours else None
                ratio = f"{pt / both:6.2f}" if (pt and both) else f"{'-':>6s}"
                cmp = peer.get("vs_ours", {}).get(ours["factorization"]) if ours else None
                print(f"{r['name']:28s} {'x'.join(map(str, r['orders'])):>6s} "
                      f"{(ours['factorization'] + ('*' if ours['requested'] == 'auto' else '') if ours else '-'):>7s} "
                      f"{fmt_ms(ours and ours['seconds_s'])} {fmt_ms(ours and ours['seconds_p'])} {fmt_ms(both)} "
                      f"{name:>6s} {fmt_ms(pt)} {ratio} {fmt_e(cmp and cmp['max_abs_dDE'])} "
                      f"{fmt_e(ours and ours.get('err_vs_reference'))} {fmt_e(peer.get('err_vs_reference'))}  "
                      f"{(cmp or {}).get('formulations_match', '-')}")
    print("ours: our factorization rule (* = the default, factorization='auto').")
    print("Times: ms, one thread. ours: CPU time, min over rounds of the median of repeats; ours s / p / s+p: one")
    print("rcwa.solve call with pol=s / p / unpolarized. peer s+p: the peer's CPU time to get both polarizations")
    print("(peer_runner; its fastest route; min over rounds of the median). ratio = peer s+p / ours s+p")
    print("(> 1: we are faster). max|dDE|: ours vs peer over all listed orders, R and T, s and p (R only")
    print("over an absorbing substrate). err: the same against meent at 3x the orders (1D) / 21x21 (2D).")


def jsonable(eff: dict) -> list[dict]:
    return [{"m": m, "n": n, **v} for (m, n), v in sorted(eff.items(), key=lambda kv: (kv[0][1], kv[0][0]))]


def run_case(cid: str, rcwa, peers: list[str], args) -> dict:
    case = CASES[cid]
    kind = len(case["structure"]["period"])
    keys = compared_keys(case)
    row = {"id": cid, "name": case["name"], "orders": case["orders"], "case": case, "peers": [],
           "compared": list(keys)}
    structure, t_build = None, 0.0
    if rcwa is not None:
        t0 = time.perf_counter()
        structure = rcwa.Structure.from_dict(case["structure"], source=f"<bench case {case['name']}>")
        t_build = time.perf_counter() - t0
    extra = tuple(f.strip() for f in getattr(args, "factorizations", "").split(",") if f.strip())
    factorizations = (OUR_FACTORIZATIONS[kind] + extra) if rcwa is not None else ()
    ours_rounds: dict[str, list[dict]] = {f: [] for f in factorizations}
    peer_rounds: dict[str, list[dict]] = {p: [] for p in peers}
    # Rounds interleave our solver and the peers, so a burst of background load hits both;
    # each side keeps the best (min) of its per-round medians.
    base_rounds: list[dict] = []
    floor_rounds: list[dict[str, float]] = []
    jobs, need, routines = floor_jobs(structure, case) if rcwa is not None else ({}, {}, {})
    servers = {p: PeerServer(case, p) for p in peers}
    try:
        for _ in range(args.rounds):
            for f in factorizations:
                ours_rounds[f].append(time_ours(rcwa, structure, case, f, args.repeats))
            if jobs:
                floor_rounds.append(floor_round(jobs, args.repeats))
            if args.base and rcwa is not None:
                base_rounds.append(run_base(cid, args))
            for p in peers:
                peer_rounds[p].append(servers[p].round(args.repeats))
    finally:
        for server in servers.values():
            server.close()
    if floor_rounds:
        row["floor"] = eigen_floor(need, floor_rounds, routines)
        row["floor_paired"] = paired_floor(rcwa, structure, case, jobs, need, args.repeats * args.rounds)
    if base_rounds:
        # The statistic of ours and of the floor: the best (min) of the per-round medians.
        row["base"] = {key: min(statistics.median(r[key]) for r in base_rounds) for key, _ in POLS}
    ours: list[dict] = []
    for f in factorizations:
        o = summarize_ours(case, f, ours_rounds[f], t_build)
        o["requested"] = f
        if all(o["factorization"] != prev["factorization"] for prev in ours):
            ours.append(o)
    row["ours"] = ours
    ref = None
    if peers and not args.no_reference:
        ref = run_peer(reference_case(case), "meent", 0)
        row["reference"] = {"peer": "meent", "orders": reference_case(case)["orders"],
                            "efficiencies": jsonable(ref["efficiencies"]), "totals": ref["totals"]}
        for o in ours:
            o["err_vs_reference"] = max_diff(o["efficiencies"], ref["efficiencies"], keys)[0]
    for p in peers:
        pr = summarize_peer(peer_rounds[p])
        pr["vs_ours"] = {}
        for o in ours:
            d, where = max_diff(o["efficiencies"], pr["efficiencies"], keys)
            cmp = {"max_abs_dDE": d, "max_abs_dDE_at": where,
                   "formulations_match": formulations_match(o["factorization"], pr.get("factorization", ""), kind),
                   "ratio": pr["seconds_both_best"] / o["seconds_both_pols"]}
            if substrate_is_lossy(case) and o.get("power_into_substrate"):
                cmp["max_abs_d_power_into_substrate"] = max(
                    abs(o["power_into_substrate"][k] - pr["totals"][k]) for k in ("T_s", "T_p"))
            pr["vs_ours"][o["factorization"]] = cmp
        if ref is not None:
            pr["err_vs_reference"] = max_diff(pr["efficiencies"], ref["efficiencies"], keys)[0]
        row["peers"].append(pr)
    return row


def run_base(cid: str, args) -> dict[str, list[float]]:
    """One round of our-side timings (CPU seconds per s, p, both) with another build of the
    solver, the site directory ``args.base`` (e.g. the base commit's wheel installed with
    ``pip install --no-deps --target``): this script in a subprocess that imports rcwa from
    there first (no site, no editable finder) and numpy from this environment."""
    import numpy

    site = Path(numpy.__file__).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=f"{args.base}{os.pathsep}{site}")
    proc = subprocess.run([sys.executable, "-S", str(Path(__file__).resolve()), "--emit-ours", "--cases", cid,
                           "--repeats", str(args.repeats)], capture_output=True, text=True, env=env, cwd=tempfile.gettempdir(),
                          timeout=3600)
    if proc.returncode != 0:
        raise BenchError(f"the base build failed on {cid} (exit {proc.returncode}):\n{proc.stderr.strip()}")
    return json.loads(proc.stdout)


def emit_ours(cid: str, repeats: int) -> int:
    """--emit-ours: one round of our timings of case ``cid`` as JSON on stdout (for run_base)."""
    rcwa = import_rcwa()
    case = CASES[cid]
    structure = rcwa.Structure.from_dict(case["structure"], source=f"<bench case {case['name']}>")
    t = time_ours(rcwa, structure, case, "auto", repeats)
    print(json.dumps({"s": t["times_s"], "p": t["times_p"], "both": t["times_both"], "rcwa": rcwa.__file__}))
    return 0


def _ratios(num: dict | None, den: dict | None) -> str:
    return " ".join(f"{num[k] / den[k]:5.2f}" if (num and den) else f"{'-':>5s}" for k in ("s", "p", "both"))


PEER_TIME_KEY = {"s": "seconds_s", "p": "seconds_p", "both": "seconds_both_best"}


def _our_seconds(row: dict) -> tuple[dict | None, dict]:
    """A case's first timing of ours (default factorization) and its seconds by polarization."""
    ours = (row.get("ours") or [None])[0]
    if ours is None:
        return None, {}
    return ours, {"s": ours["seconds_s"], "p": ours["seconds_p"], "both": ours["seconds_both_pols"]}


def print_summary(rows: list[dict]) -> None:
    """Issue 17's table: per case and polarization, ours (default factorization) against the
    fastest peer and against the case's eigen-solve floor, all CPU time in the same run."""
    head = (f"{'case':16s} {'pol':>3s} {'ours':>8s} {'fastest peer':>16s} {'ratio':>6s} | {'floor':>7s} {'/floor':>6s} "
            f"{'paired':>6s} | max|dDE| vs {', '.join(p['peer'] for p in (rows[0]['peers'] if rows else []))}")
    print()
    print(head)
    print("-" * len(head))
    for r in rows:
        ours, mine = _our_seconds(r)
        if ours is None:
            continue
        floor = r.get("floor")
        diffs = " ".join(fmt_e(p.get("vs_ours", {}).get(ours["factorization"], {}).get("max_abs_dDE")) for p in r["peers"])
        for pol in ("s", "p", "both"):
            best = min(r["peers"], key=lambda p: p[PEER_TIME_KEY[pol]], default=None)
            pt = best[PEER_TIME_KEY[pol]] if best else None
            peer = f"{best['peer']} {fmt_ms(pt, 7)}" if best else f"{'-':>16s}"
            ratio = f"{pt / mine[pol]:6.2f}" if pt else f"{'-':>6s}"
            fl = floor[pol] if floor else None
            over = f"{mine[pol] / fl:6.2f}" if fl else f"{'-':>6s}"
            paired = r.get("floor_paired")
            pair = f"{paired[pol]:6.2f}" if paired else f"{'-':>6s}"
            print(f"{r['name'] if pol == 's' else '':16s} {'s+p' if pol == 'both' else pol:>3s} {fmt_ms(mine[pol])} "
                  f"{peer:>16s} {ratio} | {fmt_ms(fl, 7)} {over} {pair} | "
                  f"{diffs if pol == 's' else ''}")
    print("CPU ms per solve (time.process_time on both sides, one BLAS/XLA thread), min over interleaved rounds")
    print("of each round's median. ours: rcwa.solve with pol=s / p / unpolarized (default factorization).")
    print("fastest peer: its CPU time for that polarization by its fastest route (s+p: one two-polarization")
    print("solve or an s and a p solve). ratio = peer / ours (goal >= 2). floor: the eigen-decompositions the")
    print("case needs timed alone with the best LAPACK routine (floor_jobs; routines in the JSON); /floor = ours /")
    print("floor (goal <= 1.3); paired: the same from back-to-back pairs, the ratio of the two minima")
    print("(paired_floor: robust to the machine's drift). max|dDE|: largest efficiency difference from each")
    print("peer (R and T, s and p; R only over an absorbing substrate).")


def print_floor_table(rows: list[dict]) -> None:
    """Ours per polarization against the eigen-solve floor and, with --base, another build."""
    head = (f"{'case':22s} {'ours s':>8s} {'p':>7s} {'s+p':>7s} | {'floor s':>8s} {'p':>7s} {'s+p':>7s} | "
            f"{'/floor s':>8s} {'p':>5s} {'s+p':>5s} | {'base s':>7s} {'p':>7s} {'s+p':>7s} | "
            f"{'gain s':>6s} {'p':>5s} {'s+p':>5s}")
    print()
    print(head)
    print("-" * len(head))
    for r in rows:
        ours, mine = _our_seconds(r)
        if ours is None:
            continue
        floor, base = r.get("floor"), r.get("base")
        print(f"{r['name']:22s} {fmt_ms(mine['s'])} {fmt_ms(mine['p'], 7)} {fmt_ms(mine['both'], 7)} | "
              f"{fmt_ms(floor and floor['s'])} {fmt_ms(floor and floor['p'], 7)} {fmt_ms(floor and floor['both'], 7)} | "
              f"   {_ratios(mine, floor)} | {fmt_ms(base and base['s'], 7)} {fmt_ms(base and base['p'], 7)} "
              f"{fmt_ms(base and base['both'], 7)} | {' ' if base else ''}{_ratios(base, mine)}")
    print("CPU ms (time.process_time, one thread), min over rounds of each round's median (ours, floor and")
    print("base alike), pol s / p / unpolarized (s+p) interleaved. floor: the eigen-decompositions the case")
    print("needs, timed alone with the best LAPACK routine (zheevd/zhegvd lossless, zgeev lossy; eigen_floor).")
    print("/floor: ours over the floor (goal <= 1.3). base: the --base build in the same run; gain = base / ours.")


# --------------------------------------------------------------------------------------------
# Mirror-symmetry sectors (issue 17 item 4): gold2d with and without them
# --------------------------------------------------------------------------------------------

SECTOR_ORDERS = ((9, 9), (15, 15))
SECTOR_WAVELENGTH_NM = 600.0
# Directions that respect gold2d's mirrors: normal incidence (both), the xz plane (y -> -y).
SECTOR_DIRECTIONS = (("normal", 0.0, 0.0), ("xz plane 20 deg", 20.0, 0.0))
# Samples of the paper table's grid (theta, phi): directions in a mirror plane or normal
# (solved in sectors), and directions off them (the general path).
TABLE_SAMPLE_MIRROR = ((0.0, 0.0), (0.0, 44.0), (20.0, 0.0), (46.0, 90.0), (70.0, 0.0), (84.0, 90.0))
TABLE_SAMPLE_GENERAL = ((20.0, 30.0), (46.0, 62.0), (70.0, 10.0), (10.0, 80.0), (84.0, 44.0), (34.0, 2.0))


def time_sectors(rcwa, structure, orders: tuple[int, int], theta: float, phi: float, repeats: int) -> dict[str, float]:
    """CPU seconds per solve (median of ``repeats`` after a warm-up, interleaved): with the
    sectors for pol s, p and s+p, and the general path (fast_paths=False) for s+p (in 2D it
    solves both polarizations whatever is asked)."""
    calls: dict[str, dict[str, str | bool]] = {"s": {"pol": "s"}, "p": {"pol": "p"}, "both": {"pol": "unpolarized"},
                                               "general": {"pol": "unpolarized", "fast_paths": False}}
    times: dict[str, list[float]] = {key: [] for key in calls}
    for key, kw in calls.items():  # warm-up, and the sectors really are used
        res = rcwa.solve(structure, SECTOR_WAVELENGTH_NM, theta, phi, orders, **kw)
        if key != "general" and "mirror_sectors" not in res.fast_paths:
            raise BenchError(f"gold2d at theta {theta}, phi {phi}: the sectors were not used ({res.fast_paths})")
    for _ in range(repeats):
        for key, kw in calls.items():
            t0 = cpu_time()
            rcwa.solve(structure, SECTOR_WAVELENGTH_NM, theta, phi, orders, **kw)
            times[key].append(cpu_time() - t0)
    return {key: statistics.median(v) for key, v in times.items()}


def _sweep_seconds(structure, settings, points, sectors: bool, repeats: int) -> float:
    """CPU seconds of one single-thread sweep over ``points`` (median of ``repeats``)."""
    import numpy as np

    from rcwa.sweep import sweep_directions

    theta = np.array([t for t, _ in points])
    phi = np.array([p for _, p in points])
    times = []
    for _ in range(repeats):
        t0 = cpu_time()
        sw = sweep_directions(structure, SECTOR_WAVELENGTH_NM, theta, phi, settings.orders, keep=settings.keep,
                              threads=1, sectors=sectors)
        times.append(cpu_time() - t0)
    expected = sum(1 for t, p in points if t == 0.0 or p % 90.0 == 0.0) if sectors else 0
    if sw.sector_points != expected:
        raise BenchError(f"the table sample solved {sw.sector_points} points in sectors, expected {expected}")
    return statistics.median(times)


def _grid_counts(theta_deg, phi_deg) -> tuple[int, int, int]:
    """Directions of a (theta, phi) grid: (all, in a mirror plane or normal, the others)."""
    import numpy as np

    from rcwa.table import GRAZING_THETA_DEG

    th, ph = np.meshgrid(np.minimum(np.array(theta_deg), GRAZING_THETA_DEG), np.array(phi_deg), indexing="ij")
    in_mirror = (th == 0.0) | (np.mod(ph, 90.0) == 0.0)
    return int(th.size), int(in_mirror.sum()), int((~in_mirror).sum())


def table_estimate(rcwa, repeats: int) -> dict:
    """The gold2d paper-preset table's single-thread time with and without the sectors,
    from sweeps over sampled directions: per-point seconds of mirror-plane (and normal)
    directions with and without sectors and of the other directions, times their counts
    in the table's grid, times the wavelengths (the per-wavelength Fourier matrices timed
    apart and added once per wavelength). Also with the sectors over the grid the table
    had before it was folded by the cell's diagonal mirror x <-> y (rcwa.symmetry:
    azimuths 0-90 deg, the x and y mirrors' range, instead of 0-45)."""
    from rcwa import symmetry
    from rcwa.solver import prepare
    from rcwa.table import PRESETS, angle_grid, settings_for

    structure = rcwa.load_structure("gold2d")
    settings = settings_for(structure, "paper")
    directions, n_mirror, n_other = _grid_counts(settings.theta_deg, settings.phi_deg)
    phi_xy = angle_grid(PRESETS["paper"]["phi_step"], *symmetry.MirrorSymmetry(True, True).azimuth_range(), "phi", cover=True)
    directions_xy, n_mirror_xy, n_other_xy = _grid_counts(settings.theta_deg, phi_xy)
    t0 = cpu_time()
    for _ in range(repeats):
        prepare(structure, SECTOR_WAVELENGTH_NM, settings.orders)
    t_prepare = (cpu_time() - t0) / repeats
    per_point = {}
    for key, points, sectors in (("mirror_sectors", TABLE_SAMPLE_MIRROR, True),
                                 ("mirror_general", TABLE_SAMPLE_MIRROR, False),
                                 ("other", TABLE_SAMPLE_GENERAL, True)):
        per_point[key] = max(0.0, _sweep_seconds(structure, settings, points, sectors, repeats) - t_prepare) / len(points)
    n_wl = len(settings.wavelengths_nm)
    without = n_wl * (t_prepare + n_mirror * per_point["mirror_general"] + n_other * per_point["other"])
    with_sectors = n_wl * (t_prepare + n_mirror * per_point["mirror_sectors"] + n_other * per_point["other"])
    without_diagonal = n_wl * (t_prepare + n_mirror_xy * per_point["mirror_sectors"] + n_other_xy * per_point["other"])
    return {"orders": list(settings.orders), "keep": list(settings.keep), "wavelengths": n_wl,
            "directions": directions, "directions_in_mirror_planes": n_mirror, "seconds_per_point": per_point,
            "seconds_prepare": t_prepare, "table_seconds_without": without, "table_seconds_with": with_sectors,
            "phi_range_deg": [settings.phi_deg[0], settings.phi_deg[-1]], "directions_without_diagonal": directions_xy,
            "table_seconds_without_diagonal": without_diagonal}


def run_sectors(rcwa, repeats: int) -> dict:
    structure = rcwa.load_structure("gold2d")
    rows = []
    for orders in SECTOR_ORDERS:
        for name, theta, phi in SECTOR_DIRECTIONS:
            print(f"[sectors] gold2d {orders[0]}x{orders[1]} {name} ...", file=sys.stderr, flush=True)
            rows.append({"orders": list(orders), "direction": name, "theta_deg": theta, "phi_deg": phi,
                         "seconds": time_sectors(rcwa, structure, orders, theta, phi, repeats)})
    print("[sectors] gold2d paper-preset table estimate ...", file=sys.stderr, flush=True)
    return {"wavelength_nm": SECTOR_WAVELENGTH_NM, "solves": rows, "table": table_estimate(rcwa, repeats)}


def print_sectors(result: dict) -> None:
    head = (f"{'gold2d':8s} {'direction':16s} {'sectors s':>10s} {'p':>7s} {'s+p':>7s} | {'general':>8s} | "
            f"{'gain s':>6s} {'s+p':>5s}")
    print()
    print(head)
    print("-" * len(head))
    for r in result["solves"]:
        t = r["seconds"]
        print(f"{r['orders'][0]:>2d} x {r['orders'][1]:<3d} {r['direction']:16s} {fmt_ms(t['s'], 10)} {fmt_ms(t['p'], 7)} "
              f"{fmt_ms(t['both'], 7)} | {fmt_ms(t['general'])} | {t['general'] / t['s']:6.1f} "
              f"{t['general'] / t['both']:5.1f}")
    print(f"CPU ms per solve at {result['wavelength_nm']:g} nm (one thread, medians): in mirror-symmetry sectors")
    print("(rcwa/cpp/sectors.hpp) for pol s / p / unpolarized, and the general path (fast_paths=False, both")
    print("polarizations). gain = general / sectors.")
    tab = result["table"]
    per = tab["seconds_per_point"]
    print(f"gold2d paper-preset table ({tab['wavelengths']} wavelengths x {tab['directions']} directions, "
          f"{tab['orders'][0]}x{tab['orders'][1]} orders), one thread, estimated from sampled sweeps:")
    print(f"  {tab['directions_in_mirror_planes']} directions per wavelength in a mirror plane or normal: "
          f"{per['mirror_general'] * 1e3:.1f} ms each without sectors, {per['mirror_sectors'] * 1e3:.1f} ms with; "
          f"the other {tab['directions'] - tab['directions_in_mirror_planes']}: {per['other'] * 1e3:.1f} ms each")
    print(f"  table: {tab['table_seconds_without'] / 60:.1f} min without sectors, {tab['table_seconds_with'] / 60:.1f} min "
          f"with (factor {tab['table_seconds_without'] / tab['table_seconds_with']:.3f}); divide by the cores a build uses")
    if "table_seconds_without_diagonal" in tab:
        print(f"  azimuths {tab['phi_range_deg'][0]:g}-{tab['phi_range_deg'][1]:g} deg (the diagonal mirror x <-> y folds "
              f"0-90 deg onto 0-45): {tab['directions']} directions instead of {tab['directions_without_diagonal']}, "
              f"{tab['table_seconds_without_diagonal'] / 60:.1f} min with sectors -> {tab['table_seconds_with'] / 60:.1f} min "
              f"(factor {tab['table_seconds_without_diagonal'] / tab['table_seconds_with']:.3f})")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT,
                    help=f"JSON results (default {DEFAULT_OUT.relative_to(ROOT)})")
    # Defaults sized so that the whole run (six cases, three peers, the sectors table) takes
    # about five minutes of CPU on the 2-core development machine.
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats per round after one warm-up (default 3)")
    ap.add_argument("--rounds", type=int, default=2, help="interleaved rounds, best median kept (default 2)")
    ap.add_argument("--peers", default=",".join(ALL_PEERS), help="comma-separated peers (default: all)")
    ap.add_argument("--cases", default=",".join(DEFAULT_CASES),
                    help=f"comma-separated subset of {list(CASES)} (default {','.join(DEFAULT_CASES)})")
    ap.add_argument("--factorizations", default="",
                    help="extra factorization rules to time ours with besides 'auto' (e.g. li,nv)")
    ap.add_argument("--no-reference", action="store_true", help="skip the high-truncation meent reference")
    side = ap.add_mutually_exclusive_group()
    side.add_argument("--peers-only", action="store_true", help="do not run our solver")
    side.add_argument("--no-peers", action="store_true", help="do not run the peers")
    ap.add_argument("--base", type=Path, default=None,
                    help="a site directory with another build of rcwa (e.g. the base commit's wheel, pip install "
                         "--no-deps --target DIR) timed in the same rounds")
    ap.add_argument("--no-sectors", action="store_true",
                    help="skip gold2d with and without mirror-symmetry sectors and the paper-table estimate")
    ap.add_argument("--sectors-only", action="store_true", help="only gold2d's sectors and the paper-table estimate")
    ap.add_argument("--emit-ours", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.emit_ours:
        return emit_ours(args.cases, args.repeats)

    try:
        if args.repeats < 1 or args.rounds < 1:
            raise BenchError(f"--repeats/--rounds: expected >= 1, got {args.repeats}/{args.rounds}")
        cases = [c.strip() for c in args.cases.split(",") if c.strip()]
        bad = [c for c in cases if c not in CASES]
        if bad:
            raise BenchError(f"--cases: unknown {bad}; expected some of {list(CASES)}")
        peers = [] if (args.no_peers or args.sectors_only) else [p.strip() for p in args.peers.split(",") if p.strip()]
        bad = [p for p in peers if p not in ALL_PEERS]
        if bad:
            raise BenchError(f"--peers: unknown {bad}; expected some of {list(ALL_PEERS)}")
        if peers:
            check_peer_env()
        rcwa = None if args.peers_only else import_rcwa()
        rows = []
        for cid in [] if args.sectors_only else cases:
            print(f"[{cid}] {CASES[cid]['name']} ...", file=sys.stderr, flush=True)
            rows.append(run_case(cid, rcwa, peers, args))
        sectors = None if (rcwa is None or args.no_sectors) else run_sectors(rcwa, args.repeats)
    except BenchError as exc:
        print(f"bench_solve: {exc}", file=sys.stderr)
        return 2

    if rows:
        print_table(rows)
        print_floor_table(rows)
        print_summary(rows)
    if sectors is not None:
        print_sectors(sectors)
    for r in rows:
        for o in r["ours"]:
            o["efficiencies"] = jsonable(o["efficiencies"])
        for p in r["peers"]:
            p["efficiencies"] = jsonable(p["efficiencies"])
    report = {
        "benchmark": "rcwa single solve, ours vs open-source peers",
        "machine": {"platform": platform.platform(), "python": platform.python_version(),
                    "cpus": os.cpu_count(), "threads": 1,
                    "load_average_at_end": list(os.getloadavg()) if hasattr(os, "getloadavg") else None},
        "repeats": args.repeats,
        "rounds": args.rounds,
        "cases": rows,
        "sectors": sectors,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    print(f"results written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

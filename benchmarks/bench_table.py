"""Benchmark: the paper-preset efficiency table of the built-in CD (``make bench``).

Prints the wall time and the size on disk of the table the paper computed (61 orders,
2 deg steps in theta and phi over 0-90 deg, 31 wavelengths; [Lange 2021, Sec. 3]:
four hours on a 4-core desktop, held as a 1.2 GB array), and for comparison one solve
at a time over the same grid (estimated from a sample), in the same run.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

import rcwa
from rcwa.table import build_table, settings_for

PAPER_HOURS = 4.0
PAPER_BYTES = 1.2e9


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None, help="where to build (default: a temporary folder, removed after)")
    parser.add_argument("--threads", type=int, default=None)
    args = parser.parse_args()
    structure = rcwa.load_structure("cd")
    settings = settings_for(structure, "paper")
    workdir = Path(args.out) if args.out else Path(tempfile.mkdtemp()) / "cd_paper.zarr"
    if workdir.exists():
        shutil.rmtree(workdir)
    directions = len(settings.theta_deg) * len(settings.phi_deg)
    print(f"cd, paper preset: {len(settings.wavelengths_nm)} wavelengths x {len(settings.theta_deg)} theta x "
          f"{len(settings.phi_deg)} phi ({directions * len(settings.wavelengths_nm)} solves), {settings.orders[0]} harmonics, "
          f"{settings.keep[0]} kept")
    report = build_table(structure, settings, workdir, threads=args.threads, progress=True)
    print(f"eigen-solves refined from a neighbouring k_x instead of solved afresh: "
          f"{report.eigen_refined} of {report.eigen_solves} ({report.eigen_refined / report.eigen_solves:.0%})")
    rng = np.random.default_rng(0)
    sample = rng.integers(0, directions, 20)
    start = time.perf_counter()
    for d in sample:
        i_theta, i_phi = divmod(d, len(settings.phi_deg))
        theta = settings.theta_deg[i_theta] if i_theta < len(settings.theta_deg) - 1 else 89.0
        rcwa.solve(structure, 550.0, theta, settings.phi_deg[i_phi], settings.orders[0], "unpolarized")
    one_at_a_time = (time.perf_counter() - start) / sample.size * directions * len(settings.wavelengths_nm)
    print(f"table built in {report.seconds:.1f} s (goal: < 120 s; paper: {PAPER_HOURS:g} h on 4 cores), "
          f"{report.bytes_on_disk / 1e6:.2f} MB on disk (goal: < 12 MB; paper: {PAPER_BYTES / 1e9:g} GB in RAM)")
    print(f"one solve at a time over the same grid (estimated from {sample.size} solves): {one_at_a_time:.0f} s; "
          f"sweep speed-up {one_at_a_time / report.seconds:.2f}x")
    if not args.out:
        shutil.rmtree(workdir.parent)


if __name__ == "__main__":
    main()

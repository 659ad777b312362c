"""Benchmark: how often the distortion-term choice (calibration.intrinsics.lens_choice.choose_terms) keeps
p1, p2, over seeds of synthetic corners (tests/calibration/lens_views.py: a pinhole of fx 500 px,
k1 -0.2, k2 0.08, 12 views reaching into the image corners, 0.05 px Gaussian corner noise).

For each case (no tangential distortion, weak p1 4e-4 / p2 -3e-4 like the synthetic datasets'
lens, strong 4e-3 / -3e-3) and each seed: the chosen set, the paired t of k1, k2 against
k1, k2, p1, p2, and the chosen fit's errors against the truth (fx relative, the principal point
in px and in its own stated std). The rates are what tests/calibration/test_lens_terms.py's
single seeds stand for::

    PYTHONPATH=. .venv/bin/python -m benchmarks.bench_lens_terms [--seeds 20]
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np

from calibration.intrinsics.lens_choice import choose_terms
from calibration.intrinsics.lens_models import fit_model
from tests.calibration.lens_views import corner_views

SIZE = (640, 480)
K = np.array([[500.0, 0.0, 322.0], [0.0, 500.0, 238.0], [0.0, 0.0, 1.0]])
CASES = {"none": [-0.2, 0.08, 0.0, 0.0, 0.0], "weak": [-0.2, 0.08, 0.0004, -0.0003, 0.0],
         "strong": [-0.2, 0.08, 0.004, -0.003, 0.0]}
VIEWS = 12
PAIR = "k1, k2 vs k1, k2, p1, p2"


def run_case(name: str, seeds: int) -> None:
    kept, ts, worst_fx, worst_z = 0, [], 0.0, 0.0
    for seed in range(seeds):
        points, corners = corner_views("pinhole", K, CASES[name], 0.0, SIZE, VIEWS, seed=seed)
        choice = choose_terms(points, corners, SIZE, cv2.CALIB_FIX_K3, "pinhole")
        fit = fit_model(points, corners, SIZE, cv2.CALIB_FIX_K3, "pinhole", choice.chosen)
        kept += "p1" in choice.chosen
        ts.append(choice.t[PAIR])
        worst_fx = max(worst_fx, abs(fit.K[0, 0] / K[0, 0] - 1))
        worst_z = max(worst_z, *np.abs((fit.K[:2, 2] - K[:2, 2]) / fit.std[2:4]))
    print(f"{name}: p1, p2 kept in {kept} of {seeds} seeds; paired t {min(ts):.2f} to {max(ts):.2f}; "
          f"fx at most {100 * worst_fx:.3f} % off; principal point at most {worst_z:.1f} of its std off")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="seeds per case (default: 20)")
    args = parser.parse_args()
    for name in CASES:
        run_case(name, args.seeds)


if __name__ == "__main__":
    main()

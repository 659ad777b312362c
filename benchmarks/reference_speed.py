"""Speed bars as ratios: a fixed reference workload timed in the same run.

The project's speed bars (`calibrate DATASET` in under 2 minutes, a report in under 30 s,
...) were set on the 2-core development machine. A bar in seconds means nothing on another
machine, and a unit test that reads the clock fails on a busy one (issue 23), so the bars
live here: each benchmark times the reference workload below in the same run, and prints its
own time as a ratio to that reference, beside the bar expressed in the same unit.

The reference is a fixed mix of the work the project spends its time on: complex LAPACK
eigen-solves of a seeded 61 x 61 matrix (the RCWA core's floor) and a numpy image pass
(calibration and reports), single-threaded through threadpoolctl so that neither the
number of cores nor a second BLAS thread moves it. Its best of ``REPEATS`` is taken (the
least disturbed by other processes). ``REFERENCE_S_AT_BARS`` is what it took on the machine
where the bars were set (2-core Xeon, best of three quiet runs on 2026-12-02 with
``python -m benchmarks.reference_speed``): a bar of B seconds there is B / that many
reference units anywhere.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

REPEATS = 5
REFERENCE_S_AT_BARS = 0.142  # the reference workload's best time on the machine the bars were set on


def _workload() -> float:
    rng = np.random.default_rng(20261202)
    a = rng.standard_normal((61, 61)) + 1j * rng.standard_normal((61, 61))
    total = 0.0
    for _ in range(12):
        total += float(np.abs(np.linalg.eigvals(a)).sum())
    image = rng.random((480, 640, 3))
    for _ in range(6):
        blurred = (image[:-2, 1:-1] + image[2:, 1:-1] + image[1:-1, :-2] + image[1:-1, 2:]) / 4.0
        total += float(np.percentile(blurred, 50))
    return total


def reference_seconds(repeats: int = REPEATS) -> float:
    """Best time of the fixed reference workload in this process, on one BLAS thread."""
    from threadpoolctl import threadpool_limits  # deferred: only benchmarks need it

    best = float("inf")
    with threadpool_limits(limits=1):
        _workload()  # warm caches and the BLAS kernels
        for _ in range(repeats):
            start = time.perf_counter()
            _workload()
            best = min(best, time.perf_counter() - start)
    return best


@dataclass(frozen=True)
class SpeedBar:
    """A bar set in seconds on the bars' machine, judged in reference units."""

    name: str
    bar_s: float

    def judge(self, seconds: float, reference_s: float) -> str:
        units, bar_units = seconds / reference_s, self.bar_s / REFERENCE_S_AT_BARS
        verdict = "met" if units < bar_units else "MISS"
        return (f"{self.name}: {seconds:.1f} s = {units:.0f} reference units (bar {bar_units:.0f}, "
                f"{self.bar_s:g} s on the bars' machine); {units / bar_units:.2f} of the bar, {verdict}")


def main() -> None:
    seconds = reference_seconds()
    print(f"reference workload: {seconds:.3f} s here, {REFERENCE_S_AT_BARS:.3f} s on the bars' machine "
          f"(this machine is {seconds / REFERENCE_S_AT_BARS:.2f}x that time)")


if __name__ == "__main__":
    main()

"""Benchmark: time per re-render of the fit preset after a parameter change (``make bench``).

Calibration re-renders hundreds of times (renderer.rerender.FitRenderer); this prints the
set-up time and the median time of a re-render after the pose, focal length, exposure
and light power changed.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from renderer.rerender import FIT_RESOLUTION, FIT_SPP, FitRenderer


def main() -> None:
    parser = argparse.ArgumentParser(description="time per re-render after a parameter change (fit preset)")
    parser.add_argument("--scene", default="cornell_cd")
    parser.add_argument("--repeats", type=int, default=10)
    args = parser.parse_args()
    start = time.perf_counter()
    fit = FitRenderer(args.scene)
    fit.render()  # compile
    setup = time.perf_counter() - start
    rng = np.random.default_rng(0)
    times = []
    for i in range(args.repeats):
        cam = fit.camera
        moved = dataclasses.replace(cam, world_to_camera=cam.world_to_camera.copy(), fx=cam.fx * (1 + rng.normal(0, 0.01)),
                                    fy=cam.fy * (1 + rng.normal(0, 0.01)))
        moved.world_to_camera[:3, 3] += rng.normal(0, 0.005, 3)
        t = time.perf_counter()
        fit.set(camera=moved, exposure=1.0 + 0.1 * i, light_power_scale=1.0 + 0.05 * i)
        fit.render(seed=i)
        times.append(time.perf_counter() - t)
    print(f"fit preset, {args.scene} at {FIT_RESOLUTION[0]}x{FIT_RESOLUTION[1]}, {FIT_SPP} spp: setup {setup:.1f} s, "
          f"re-render after a parameter change {np.median(times) * 1e3:.0f} ms (median of {args.repeats}; aim: well under 1 s)")


if __name__ == "__main__":
    main()

"""Benchmark: draft and paper presets of cornell_cd (``make bench``).

Prints samples per second and wall time of the draft preset, and for the paper preset
(978 x 734, 2045 spp; Lange et al. 2021 rendered it in 22 minutes on a 4-core desktop)
its samples per second measured on a few passes and the estimated time of the full frame.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

PAPER_MINUTES_4_CORES = 22.0


def main() -> None:
    from renderer.render import PRESETS, render

    with tempfile.TemporaryDirectory() as tmp:
        info = render("cornell_cd", Path(tmp) / "draft.exr", preset="draft", progress=False)
        w, h = info["resolution"]
        sps = w * h * info["spp"] / sum(info["seconds_per_pass"])
        print(f"draft: {w}x{h}, {info['spp']} spp in {info['seconds_total']:.1f} s wall ({sps:.3g} samples/s, {info['variant']})")
        paper = PRESETS["paper"]
        probe_spp = 2 * paper["pass_spp"]
        start = time.perf_counter()
        info = render("cornell_cd", Path(tmp) / "paper_probe.exr", preset="paper", spp=probe_spp, progress=False)
        w, h = info["resolution"]
        sps = w * h * info["spp"] / sum(info["seconds_per_pass"])
        estimate = w * h * paper["spp"] / sps / 60
        print(f"paper: {w}x{h}, {probe_spp} spp measured ({sps:.3g} samples/s, {time.perf_counter() - start:.1f} s with setup); "
              f"the full {paper['spp']} spp frame is estimated at {estimate:.1f} min on this machine "
              f"(paper: {PAPER_MINUTES_4_CORES:g} min on 4 cores; same spp, not yet the same noise level)")


if __name__ == "__main__":
    main()

"""Benchmark: draft and paper presets of cornell_cd (``make bench``).

Prints samples per second and wall time of the draft preset, and for the paper preset
(978 x 734, 2045 spp; [Lange 2021] rendered it in 22 minutes on a 4-core desktop)
its samples per second measured on a few passes and the estimated time of the full frame.

Then the time at the paper's noise level. Paper mode at 2045 spp stands in for the
paper's renderer (its Eqs. 2-5, its spp). Each mode's relative pixel noise is measured
from two seeds at ``NOISE_SPP`` on a smaller frame (noise per pixel depends on spp, not
on resolution): sigma = RMS(a - b) / sqrt(2) / mean((a + b) / 2), over the whole frame
and over the CD. Noise falls as 1 / sqrt(spp), so improved mode reaches paper mode's
2045-spp noise at 2045 (sigma_improved / sigma_paper)^2 spp; its time follows from the
paper preset's samples per second.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

PAPER_MINUTES_4_CORES = 22.0
NOISE_SPP = 128
NOISE_RESOLUTION = (320, 240)


def relative_noise(a, b, mask=None) -> float:
    if mask is not None:
        a, b = a[mask], b[mask]
    return float(np.sqrt(np.mean((a - b) ** 2) / 2) / np.mean(np.abs(a + b) / 2))


def noise_per_mode(spp: int = NOISE_SPP, resolution=NOISE_RESOLUTION) -> dict:
    """Relative pixel noise of paper and improved mode (whole frame, CD) at ``spp``."""
    from renderer.variant import set_variant

    set_variant()
    import mitsuba as mi

    from renderer.accuracy import element_mask
    from renderer.mitsuba_scene import scene_dict
    from renderer.render import with_resolution
    from renderer.scene import load_scene

    spec = with_resolution(load_scene("cornell_cd"), resolution)
    out = {}
    for mode in ("paper", "improved"):
        d, _ = scene_dict(mi, spec, spp=spp, mode=mode)
        mask = element_mask(mi, d)
        sc = mi.load_dict(d)
        # Mitsuba's stub types seed as mi.UInt32, yet mi.render takes a Python int (its own default is 0).
        a, b = (np.array(mi.render(sc, seed=s)) for s in (1, 2))  # type: ignore[arg-type]
        out[mode] = {"frame": relative_noise(a, b), "cd": relative_noise(a, b, mask)}
    return out


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
              f"(paper: {PAPER_MINUTES_4_CORES:g} min on 4 cores; same spp)")
    noise = noise_per_mode()
    print(f"relative pixel noise at {NOISE_SPP} spp (two seeds, {NOISE_RESOLUTION[0]}x{NOISE_RESOLUTION[1]}): "
          + ", ".join(f"{m} {n['frame']:.4f} frame / {n['cd']:.4f} CD" for m, n in noise.items()))
    for region in ("frame", "cd"):
        need = paper["spp"] * (noise["improved"][region] / noise["paper"][region]) ** 2
        minutes = w * h * need / sps / 60
        print(f"improved mode at paper mode's {paper['spp']}-spp noise on the {region}: {need:.0f} spp, "
              f"estimated {minutes:.1f} min on this machine (goal: under {PAPER_MINUTES_4_CORES:g} min)")


if __name__ == "__main__":
    main()

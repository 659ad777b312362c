"""Benchmarks of the BWDF (``make bench``): speed against Mitsuba's conductor, and noise at
equal time for paper and improved modes.

The scene is Mitsuba's Cornell box with a CD-like disk (radial grooves, the built-in
``cd`` table) on the floor; issue 5 replaces it with the measured box and the real CD.
1. Samples per second with the BWDF on the disk against a conductor on the same disk, at
   the same spp (goal: at least 0.9x).
2. Noise at equal time: relative RMS error on the disk's pixels against a converged
   reference (improved mode, many spp), for paper and improved modes given the same
   wall time (goal: improved at least 2x lower).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

TABLE_DIR = Path("build/tables")


def cd_table(path: Path | None = None) -> Path:
    import rcwa
    from rcwa.table import build_table, settings_for

    path = path or TABLE_DIR / "cd_bench.zarr"
    s = rcwa.load_structure("cd")
    st = settings_for(s, "draft", wavelengths="360:830:48", theta_step=3.0, phi_step=6.0, orders=31, keep=11)
    path.parent.mkdir(parents=True, exist_ok=True)
    build_table(s, st, path, progress=True)
    return path


def scene(mi, disk_bsdf: dict, resolution: int, spp: int):
    box = mi.cornell_box()
    box["sensor"]["film"]["width"] = box["sensor"]["film"]["height"] = resolution
    box["sensor"]["sampler"] = {"type": "independent", "sample_count": spp}
    box.pop("small-box", None)
    box.pop("large-box", None)
    box["cd"] = {"type": "disk", "bsdf": disk_bsdf,
                 "to_world": mi.ScalarTransform4f().translate([0.0, -0.99, 0.1]).rotate([1, 0, 0], -90).scale(0.45)}
    return mi.load_dict(box)


def disk_mask(mi, resolution: int) -> np.ndarray:
    black = np.array(mi.render(scene(mi, {"type": "diffuse", "reflectance": 0.0}, resolution, 4), seed=0))
    white = np.array(mi.render(scene(mi, {"type": "diffuse", "reflectance": 1.0}, resolution, 4), seed=0))
    return np.abs(white - black).sum(-1) > 1e-6


def timed_render(mi, sc, seed: int = 0) -> tuple[np.ndarray, float]:
    start = time.perf_counter()
    image = np.array(mi.render(sc, seed=seed))
    return image, time.perf_counter() - start


def samples_per_second(mi, table: Path, resolution: int, spp: int) -> dict:
    out = {}
    for name, bsdf in (("bwdf", {"type": "bwdf", "filename": str(table), "mapping": "radial"}),
                       ("conductor", {"type": "conductor", "material": "Al"})):
        sc = scene(mi, bsdf, resolution, spp)
        timed_render(mi, sc)  # compile
        _, seconds = timed_render(mi, sc, seed=1)
        out[name] = resolution * resolution * spp / seconds
    return out


def noise_at_equal_time(mi, table: Path, resolution: int, budget_s: float, reference_spp: int) -> dict:
    mask = disk_mask(mi, resolution)
    ref_scene = scene(mi, {"type": "bwdf", "filename": str(table), "mapping": "radial", "mode": "improved"}, resolution, reference_spp)
    reference, _ = timed_render(mi, ref_scene, seed=123)
    results = {}
    for mode in ("paper", "improved"):
        probe = scene(mi, {"type": "bwdf", "filename": str(table), "mapping": "radial", "mode": mode}, resolution, 16)
        timed_render(mi, probe)
        _, t16 = timed_render(mi, probe, seed=2)
        spp = max(1, int(budget_s / t16 * 16))
        sc = scene(mi, {"type": "bwdf", "filename": str(table), "mapping": "radial", "mode": mode}, resolution, spp)
        image, seconds = timed_render(mi, sc, seed=3)
        ref = reference[mask]
        rel = np.sqrt(np.mean((image[mask] - ref) ** 2)) / np.mean(np.abs(ref))
        results[mode] = {"spp": spp, "seconds": seconds, "relative_rms_error": float(rel)}
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--budget", type=float, default=3.0, help="seconds per mode for the equal-time comparison")
    parser.add_argument("--reference-spp", type=int, default=4096)
    args = parser.parse_args()
    from renderer.variant import set_variant

    variant = set_variant()
    import mitsuba as mi

    from renderer.bwdf import register

    register()
    table = cd_table()
    sps = samples_per_second(mi, table, args.resolution, args.spp)
    print(f"[{variant}] samples/s at {args.resolution}^2 x {args.spp} spp: BWDF {sps['bwdf']:.3g}, "
          f"conductor {sps['conductor']:.3g}; ratio {sps['bwdf'] / sps['conductor']:.2f} (goal >= 0.9)")
    noise = noise_at_equal_time(mi, table, args.resolution, args.budget, args.reference_spp)
    for mode, r in noise.items():
        print(f"{mode:>8}: {r['spp']} spp in {r['seconds']:.2f} s, relative RMS error on the CD {r['relative_rms_error']:.4f}")
    print(f"error ratio paper/improved at equal time: {noise['paper']['relative_rms_error'] / noise['improved']['relative_rms_error']:.2f} (goal >= 2)")


if __name__ == "__main__":
    main()

"""Benchmark of the BWDF (``make bench``): speed against Mitsuba's conductor. (Noise at
equal time is measured on the real cornell_cd scene by benchmarks.bench_noise.)

The scene is Mitsuba's Cornell box with a CD-like disk (radial grooves, the built-in
``cd`` table) on the floor: the same disk with either material, so that only the
material's cost differs.
1. Samples per second with the BWDF on the disk against a conductor on the same disk, at
   the same spp (goal: at least 0.9x).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from renderer.accuracy import timed_render

TABLE_DIR = Path("build/tables")
DISK_CENTER = [0.0, -0.99, 0.1]  # where the disk lies in Mitsuba's Cornell box: the grooves' centre


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
                 "to_world": mi.ScalarTransform4f().translate(DISK_CENTER).rotate([1, 0, 0], -90).scale(0.45)}
    return mi.load_dict(box)


def samples_per_second(mi, table: Path, resolution: int, spp: int, repeats: int = 5) -> dict:
    """Samples per second of each disk material, from the fastest of ``repeats`` renders
    taken in turn (alternating, so that load from other work on a shared machine hits
    both alike)."""
    scenes = {name: scene(mi, bsdf, resolution, spp) for name, bsdf in (
        ("bwdf", {"type": "bwdf", "filename": str(table), "mapping": "radial", "center": DISK_CENTER}),
        ("conductor", {"type": "conductor", "material": "Al"}))}
    best = {name: math.inf for name in scenes}
    for sc in scenes.values():
        timed_render(mi, sc, seed=0)  # compile
    for r in range(repeats):
        for name, sc in scenes.items():
            best[name] = min(best[name], timed_render(mi, sc, seed=1 + r)[1])
    return {name: resolution * resolution * spp / seconds for name, seconds in best.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--spp", type=int, default=64)
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


if __name__ == "__main__":
    main()

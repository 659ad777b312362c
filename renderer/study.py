"""``workbench study render``: what rendering accuracy costs in time, for the BWDF.

Writes JSON, CSV and plots (PNG, SVG) for the HTML report:
1. error versus wall time: relative RMS error on the diffractive element against a
   converged reference (improved mode, many spp), for paper and improved modes at
   increasing spp;
2. paper mode's bias and colour shift against Delta (its Eq. 4-5 tolerance), measured as
   the relative error of the element's mean radiance and the change of its chromaticity
   (r/(r+g+b), g/(r+g+b)) against the reference, at high spp;
3. each mode's energy error in a furnace (a lossless see-through grating; see
   tests/renderer/test_bwdf_energy.py).
The scene is the provisional CD-in-Cornell-box of renderer.bench_bwdf until scene files
exist (issue 5).
"""

from __future__ import annotations

import csv
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class RenderStudyConfig:
    resolution: int = 96
    spp_steps: tuple[int, ...] = (16, 64, 256)
    reference_spp: int = 2048
    deltas: tuple[float, ...] = (0.02, 0.05, 0.1, 0.2)
    delta_spp: int = 512
    furnace_samples: int = 200_000


def run_render_study(out: str | Path, cfg: RenderStudyConfig = RenderStudyConfig()) -> dict:
    from renderer.variant import set_variant

    variant = set_variant()
    import mitsuba as mi

    from renderer import bench_bwdf as bench
    from renderer.bwdf import register

    register()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    table = bench.cd_table()
    mask = bench.disk_mask(mi, cfg.resolution)
    cd = lambda **kw: {"type": "bwdf", "filename": str(table), "mapping": "radial", **kw}  # noqa: E731
    reference, _ = bench.timed_render(mi, bench.scene(mi, cd(mode="improved"), cfg.resolution, cfg.reference_spp), seed=99)
    ref = reference[mask]

    def rel_rms(image):
        return float(np.sqrt(np.mean((image[mask] - ref) ** 2)) / np.mean(np.abs(ref)))

    curve = []
    for mode in ("paper", "improved"):
        for spp in cfg.spp_steps:
            sc = bench.scene(mi, cd(mode=mode), cfg.resolution, spp)
            bench.timed_render(mi, sc)
            image, seconds = bench.timed_render(mi, sc, seed=7)
            curve.append({"mode": mode, "spp": spp, "seconds": seconds, "relative_rms_error": rel_rms(image)})

    def chroma(values):
        total = values.sum(axis=-1, keepdims=True)
        return (values / np.maximum(total, 1e-12))[..., :2].mean(axis=0)

    bias = []
    for delta in cfg.deltas:
        image, _ = bench.timed_render(mi, bench.scene(mi, cd(mode="paper", delta=delta), cfg.resolution, cfg.delta_spp), seed=5)
        bias.append({"delta": delta, "mean_relative_error": float(image[mask].mean() / ref.mean() - 1),
                     "chromaticity_shift": float(np.linalg.norm(chroma(image[mask]) - chroma(ref)))})

    energy = _furnace_energies(mi, out, cfg.furnace_samples)
    data = {"variant": variant, "config": asdict(cfg), "error_vs_time": curve, "delta_bias": bias, "energy": energy,
            "reference_spp": cfg.reference_spp}
    (out / "study_render.json").write_text(json.dumps(data, indent=2))
    for name, rows in (("render_error_vs_time", curve), ("render_delta_bias", bias), ("render_energy", energy)):
        with open(out / f"{name}.csv", "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=sorted(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    _plot(curve, bias, out)
    return data


def _furnace_energies(mi, out: Path, samples: int) -> list[dict]:
    import drjit as dr

    import rcwa
    from rcwa.table import build_table, settings_for

    s = rcwa.Structure.from_dict({"period": [0.6], "superstrate": "air", "substrate": "air", "layers": [
        {"thickness": 0.08, "material": "air", "shapes": [{"material": {"n": 1.3}, "x": [0.0, 0.3]}]}]})
    st = settings_for(s, "draft", wavelengths="450:650:3", theta_step=2.0, phi_step=6.0, orders=21, keep=5, both_sides=True)
    path = out / "furnace_table.zarr"
    build_table(s, st, path, progress=False, force=True)
    rows = []
    rng = np.random.default_rng(0)
    cos_t = rng.uniform(-1, 1, samples)
    phi = rng.uniform(0, 2 * np.pi, samples)
    sin_t = np.sqrt(1 - cos_t**2)
    for mode in ("paper", "improved"):
        bsdf = mi.load_dict({"type": "bwdf", "filename": str(path), "mode": mode})
        si = dr.zeros(mi.SurfaceInteraction3f, samples)
        si.wi = mi.Vector3f(sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t)
        si.wavelengths = mi.Spectrum(*[mi.Float(w) for w in rng.uniform(460, 640, (4, samples))])
        _, w = bsdf.sample(mi.BSDFContext(), si, mi.Float(rng.random(samples)), mi.Point2f(0.5, 0.5))
        rows.append({"mode": mode, "energy": float(np.array(w).mean()), "energy_error": float(np.array(w).mean() - 1)})
    return rows


def _plot(curve, bias, out: Path) -> None:
    from workbench.plots import new_figure, save_figure

    fig, axes = new_figure()
    for mode in ("paper", "improved"):
        rows = [r for r in curve if r["mode"] == mode]
        axes[0].loglog([r["seconds"] for r in rows], [r["relative_rms_error"] for r in rows], "o-", label=mode)
    axes[0].set(xlabel="wall time (s)", ylabel="relative RMS error on the CD", title="render error versus time")
    axes[1].plot([b["delta"] for b in bias], [b["mean_relative_error"] for b in bias], "o-", label="mean radiance error")
    axes[1].plot([b["delta"] for b in bias], [b["chromaticity_shift"] for b in bias], "s-", label="chromaticity shift")
    axes[1].set(xlabel="Delta (paper mode)", title="paper mode: bias against Delta")
    save_figure(fig, axes, out, "study_render")

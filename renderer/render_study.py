"""``workbench study render SCENE``: what rendering accuracy costs in time, for the BWDF.

Writes JSON, CSV and plots (PNG, SVG) for the HTML report, measured on the scene's
diffractive elements (CDs and gratings; the film is cropped to them, as in
renderer.accuracy, so every sample is spent where the comparison is made):
1. error versus wall time: relative RMS error and relative MSE against a converged
   reference (two improved-mode renders at ``reference_spp``, whose own noise is
   subtracted; renderer.accuracy.errors), for paper and improved modes at
   increasing spp;
2. paper mode's bias and colour shift against Delta (its Eq. 4-5 tolerance), measured as
   the relative error of the elements' mean radiance and the change of their
   chromaticity (r/(r+g+b), g/(r+g+b)) against the reference, at ``delta_spp``;
3. each mode's energy error in a furnace (a lossless see-through grating; see
   tests/renderer/test_bwdf_energy.py).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from renderer import accuracy
from renderer.variant import set_variant
from workbench.core.files import atomic_write_csv, atomic_write_text
from workbench.core.plots import new_figure, save_figure
from workbench.core.version import versions


@dataclass(frozen=True)
class RenderStudyConfig:
    resolution: tuple[int, int] = (640, 480)
    spp_steps: tuple[int, ...] = (64, 256, 1024)
    reference_spp: int = 4096
    deltas: tuple[float, ...] = (0.02, 0.05, 0.1, 0.2)
    delta_spp: int = 1024
    furnace_samples: int = 200_000
    seed: int = 0  # every render's and the furnace's draws: another seed is another realisation of the study


MEDIAN_OF_MEANS_BLOCKS = 20  # blocks of the furnace's weights (median_of_means)


def _seed(cfg: RenderStudyConfig, base: int) -> int:
    """The render seed of one of the study's renders (``base`` at cfg.seed 0; apart for other seeds)."""
    return base + 10_000 * cfg.seed


def _chromaticity(values: np.ndarray) -> np.ndarray:
    total = values.sum(axis=-1, keepdims=True)
    return (values / np.maximum(total, 1e-12))[..., :2].mean(axis=0)


def run_render_study(scene: str | Path, out: str | Path, cfg: RenderStudyConfig = RenderStudyConfig(), *,
                     progress: bool = True) -> dict:
    """Render error against time on the scene's diffractive elements (see the module's docstring).

    ``progress``: a progress bar over the renders (references, each mode's spp steps,
    paper mode's Delta values, the furnace test)."""
    started = time.perf_counter()
    variant = set_variant()
    # deferred: mitsuba and the BWDF after set_variant; these pull in mitsuba, the RCWA core and cv2, and
    # `workbench --help` imports this module
    import mitsuba as mi

    from renderer.bwdf import register
    from renderer.render import with_resolution
    from renderer.scene import load_scene

    register()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    spec = with_resolution(load_scene(scene), cfg.resolution)
    crop, mask = accuracy.element_crop(mi, spec)
    steps = 2 + 2 * (1 + len(cfg.spp_steps)) + len(cfg.deltas) + 1
    bar = tqdm(total=steps, desc=f"study {spec.name}", unit="render", disable=not progress)
    ref_scene = accuracy.load_cropped(mi, spec, "improved", crop)
    ref_a, _ = accuracy.timed_render(mi, ref_scene, seed=_seed(cfg, 1001), spp=cfg.reference_spp)
    ref_b, _ = accuracy.timed_render(mi, ref_scene, seed=_seed(cfg, 1002), spp=cfg.reference_spp)
    bar.update(2)
    curve = _error_curve(mi, spec, crop, (ref_a, ref_b), mask, cfg, bar)
    bias = _delta_bias(mi, spec, crop, ((ref_a + ref_b) / 2)[mask], mask, cfg, bar)
    energy = _furnace_energies(mi, out, cfg.furnace_samples, cfg.seed)
    bar.update(1)
    bar.close()
    data = {"variant": variant, "scene": spec.name, "config": asdict(cfg), "crop": crop, "element_pixels": int(mask.sum()),
            "error_vs_time": curve, "delta_bias": bias, "energy": energy, "reference_spp": cfg.reference_spp,
            "versions": versions("mitsuba", "drjit", "numpy"), "timings": {"total_s": time.perf_counter() - started}}
    atomic_write_text(out / "study_render.json", json.dumps(data, indent=2))
    for name, rows in (("render_error_vs_time", curve), ("render_delta_bias", bias), ("render_energy", energy)):
        atomic_write_csv(out / f"{name}.csv", rows)
    _plot(curve, bias, out)
    return data


def _error_curve(mi, spec, crop, references: tuple[np.ndarray, np.ndarray], mask: np.ndarray, cfg: RenderStudyConfig,
                 bar) -> list[dict]:
    """Each mode's error against the references (renderer.accuracy.errors) and wall time, per spp step."""
    curve = []
    for mode in ("paper", "improved"):
        sc = accuracy.load_cropped(mi, spec, mode, crop)
        accuracy.timed_render(mi, sc, seed=0, spp=cfg.spp_steps[0])  # compile
        bar.update(1)
        for spp in cfg.spp_steps:
            image, seconds = accuracy.timed_render(mi, sc, seed=_seed(cfg, 7), spp=spp)
            e = accuracy.errors(image, *references, mask)
            curve.append({"mode": mode, "spp": spp, "seconds": seconds, "relative_rms_error": e["relative_rms_error"],
                          "relative_mse": e["relative_mse"]})
            bar.update(1)
    return curve


def _delta_bias(mi, spec, crop, ref: np.ndarray, mask: np.ndarray, cfg: RenderStudyConfig, bar) -> list[dict]:
    """Paper mode's mean radiance error and chromaticity shift against the reference ``ref``, per Delta."""
    bias = []
    for delta in cfg.deltas:
        sc = accuracy.load_cropped(mi, spec, "paper", crop, delta=delta)
        image, _ = accuracy.timed_render(mi, sc, seed=_seed(cfg, 5), spp=cfg.delta_spp)
        bias.append({"delta": delta, "mean_relative_error": float(image[mask].mean() / ref.mean() - 1),
                     "chromaticity_shift": float(np.linalg.norm(_chromaticity(image[mask]) - _chromaticity(ref)))})
        bar.update(1)
    return bias


def _furnace_energies(mi, out: Path, samples: int, seed: int = 0) -> list[dict]:
    import drjit as dr  # deferred: start-up time

    import rcwa  # deferred: as run_render_study's imports
    from rcwa.table import build_table, settings_for  # deferred: as above

    s = rcwa.Structure.from_dict({"period": [0.6], "superstrate": "air", "substrate": "air", "layers": [
        {"thickness": 0.08, "material": "air", "shapes": [{"material": {"n": 1.3}, "x": [0.0, 0.3]}]}]})
    st = settings_for(s, "draft", wavelengths="450:650:3", theta_step=2.0, phi_step=6.0, orders=21, keep=5, both_sides=True)
    path = out / "furnace_table.zarr"
    build_table(s, st, path, progress=False, force=True)
    rows = []
    rng = np.random.default_rng(seed)
    cos_t = rng.uniform(-1, 1, samples)
    phi = rng.uniform(0, 2 * np.pi, samples)
    sin_t = np.sqrt(1 - cos_t**2)
    for mode in ("paper", "improved"):
        bsdf = mi.load_dict({"type": "bwdf", "filename": str(path), "mode": mode})
        si = dr.zeros(mi.SurfaceInteraction3f, samples)
        si.wi = mi.Vector3f(sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t)
        si.wavelengths = mi.Spectrum(*[mi.Float(w) for w in rng.uniform(460, 640, (4, samples))])
        _, w = bsdf.sample(mi.BSDFContext(), si, mi.Float(rng.random(samples)), mi.Point2f(0.5, 0.5))
        weights = np.array(w).mean(axis=0)  # the sample weight, averaged over the hero wavelengths' channels
        rows.append({"mode": mode, "energy": float(weights.mean()), "energy_error": float(weights.mean() - 1),
                     "energy_median_of_means": median_of_means(weights)})
    return rows


def median_of_means(values: np.ndarray, blocks: int = MEDIAN_OF_MEANS_BLOCKS) -> float:
    """The median of the means of ``blocks`` equal consecutive blocks [Nemirovsky & Yudin 1983;
    Lugosi & Mendelson 2019, Sec. 2]: an estimate of the mean that a rare huge value cannot
    move. Paper mode's furnace weights need it: its cos(theta_i)/cos(theta_o) factor at grazing
    exits gives P(W > w) ~ 8e-3 w^-1.2 (measured over 2e6 samples: finite mean, infinite
    variance), so the plain mean of 50,000 samples ranged 0.99-1.25 over 40 seeds. Biased low by
    the tail beyond a block's largest typical weight (about 0.02 here), which the mean keeps."""
    usable = len(values) // blocks * blocks
    return float(np.median(np.asarray(values[:usable], float).reshape(blocks, -1).mean(axis=1)))


def _plot(curve, bias, out: Path) -> None:

    fig, axes = new_figure()
    for mode in ("paper", "improved"):
        rows = [r for r in curve if r["mode"] == mode]
        axes[0].loglog([r["seconds"] for r in rows], [r["relative_rms_error"] for r in rows], "o-", label=mode)
    axes[0].set(xlabel="wall time (s)", ylabel="relative RMS error on the diffractive elements", title="render error versus time")
    axes[1].plot([b["delta"] for b in bias], [b["mean_relative_error"] for b in bias], "o-", label="mean radiance error")
    axes[1].plot([b["delta"] for b in bias], [b["chromaticity_shift"] for b in bias], "s-", label="chromaticity shift")
    axes[1].set(xlabel="Delta (paper mode)", title="paper mode: bias against Delta")
    save_figure(fig, axes, out, "study_render")

"""Noise at equal time on the real scene (``make bench``): the CD of ``cornell_cd``,
rendered in paper and improved modes for the same wall time, against a converged
reference.

Method. The film is cropped to the CD (found by tracing primary rays to its polycarbonate
top), so every sample is spent where the comparison is made. Two independent improved-mode
references A and B at ``reference_spp`` give the reference's own noise: for an image I,
E|I - A|^2 = E|I - truth|^2 + E|A - truth|^2 and E|A - B|^2 = 2 E|A - truth|^2, so
|I - A|^2 - |A - B|^2 / 2 estimates I's error against the truth without the reference's
noise (the error of paper mode then includes its bias: its Delta test and cos ratio).
Each mode renders for about ``budget_s``; its error is then scaled to exactly the budget
by sqrt(seconds / budget) (Monte Carlo error falls as one over the square root of time).

Two error measures on the CD's pixels, both standard: the relative RMS error
(RMS of I - truth over the mean of the truth), dominated by the brightest pixels (the
light's mirror image), and the relative MSE of Rousselle et al. 2011 (mean over pixels
of (I - truth)^2 / (truth^2 + eps), eps = 1e-2 times the mean squared truth), which
weighs every pixel alike.
"""

from __future__ import annotations

import argparse

import numpy as np

from workbench.timing import timed

RELMSE_EPS = 1e-2


ELEMENT_PREFIXES = ("cd", "grating")  # scene keys of diffractive elements (renderer.build), CD tops included


def element_mask(mi, scene_d: dict) -> np.ndarray:
    """Pixels of the (uncropped) film whose primary ray hits a diffractive element (a CD,
    its polycarbonate top, a grating)."""
    sc = mi.load_dict(scene_d)
    sensor = sc.sensors()[0]
    W, H = sensor.film().crop_size()
    y, x = np.mgrid[0:H, 0:W]
    ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(((x + 0.5) / W).ravel().astype(np.float32),
                                                    ((y + 0.5) / H).ravel().astype(np.float32)), mi.Point2f(0.5, 0.5))
    si = sc.ray_intersect(ray)
    hit = np.zeros(W * H, bool)
    for s in sc.shapes():
        if s.id().startswith(ELEMENT_PREFIXES):
            hit |= np.array(si.shape == mi.ShapePtr(s))
    return hit.reshape(H, W)


def element_crop(mi, spec, margin: int = 2) -> tuple[tuple[list[int], list[int]], np.ndarray]:
    """((offset, size) of the film region the scene's diffractive elements cover, their
    mask over that region). Raises UserInputError when the camera sees none."""
    from renderer.build import scene_dict
    from workbench.errors import UserInputError

    d, _ = scene_dict(mi, spec, spp=1)
    hit = element_mask(mi, d)
    if not hit.any():
        raise UserInputError("the camera sees no diffractive element (CD or grating) to measure", field="scene",
                             expected="a scene whose camera sees a [[cd]] or [[grating]]", got=spec.name)
    H, W = hit.shape
    ys, xs = np.nonzero(hit)
    x0, y0 = max(xs.min() - margin, 0), max(ys.min() - margin, 0)
    x1, y1 = min(xs.max() + margin + 1, W), min(ys.max() + margin + 1, H)
    return ([int(x0), int(y0)], [int(x1 - x0), int(y1 - y0)]), hit[y0:y1, x0:x1]


def load_cropped(mi, spec, mode: str, crop, *, delta: float | None = None, spp: int = 64):
    """The scene in ``mode``, its film cropped; ``delta`` sets paper mode's Delta."""
    from renderer.build import scene_dict

    d, _ = scene_dict(mi, spec, spp=spp, mode=mode)
    if delta is not None:
        for key, obj in d.items():
            if key.startswith(ELEMENT_PREFIXES) and isinstance(obj, dict) and obj.get("bsdf", {}).get("type") == "bwdf":
                obj["bsdf"]["delta"] = delta
    (x, y), (w, h) = crop
    d["sensor"]["film"].update(crop_offset_x=x, crop_offset_y=y, crop_width=w, crop_height=h)
    return mi.load_dict(d)


def timed_render(mi, sc, seed: int, spp: int = 0) -> tuple[np.ndarray, float]:
    return timed(lambda: np.array(mi.render(sc, seed=seed, spp=spp)))


def _spp_for(mi, scene, budget_s: float) -> int:
    """Samples per pixel that fill ``budget_s``: timed at 64 spp, then again at the spp
    estimated for a quarter of the budget (a render's fixed cost distorts the first
    estimate)."""
    spp = 64
    timed_render(mi, scene, seed=0, spp=spp)  # compile
    for share in (0.25, 1.0):
        _, seconds = timed_render(mi, scene, seed=1, spp=spp)
        spp = max(1, int(budget_s * share / seconds * spp))
    return spp


def errors(image: np.ndarray, ref_a: np.ndarray, ref_b: np.ndarray, mask: np.ndarray) -> dict:
    """Relative RMS error and relative MSE against the truth, the references' noise removed."""
    i, a, b = image[mask], ref_a[mask], ref_b[mask]
    sq = np.sum((i - a) ** 2, axis=-1)
    ref_noise = np.sum((a - b) ** 2, axis=-1) / 2
    truth2 = np.sum(((a + b) / 2) ** 2, axis=-1)
    scale = np.mean(np.abs((a + b) / 2))
    rel_rms = np.sqrt(max(np.mean(sq - ref_noise), 0.0) / 3) / scale
    rel_mse = max(float(np.mean((sq - ref_noise) / (truth2 + RELMSE_EPS * np.mean(truth2)))), 0.0)
    return {"relative_rms_error": float(rel_rms), "relative_mse": rel_mse,
            "reference_relative_rms_noise": float(np.sqrt(np.mean(ref_noise) / 3) / scale)}


def noise_at_equal_time(scene: str = "cornell_cd", resolution=(640, 480), budget_s: float = 20.0,
                        reference_spp: int = 4096, modes=("paper", "improved")) -> dict:
    from renderer.variant import set_variant

    variant = set_variant()
    import mitsuba as mi

    from renderer.render import with_resolution
    from renderer.scene import load_scene

    spec = with_resolution(load_scene(scene), resolution)
    crop, mask = element_crop(mi, spec)
    ref_scene = load_cropped(mi, spec, "improved", crop)
    ref_a, ref_seconds = timed_render(mi, ref_scene, seed=1001, spp=reference_spp)
    ref_b, _ = timed_render(mi, ref_scene, seed=1002, spp=reference_spp)
    out = {"variant": variant, "scene": spec.name, "resolution": list(resolution), "crop_offset": crop[0],
           "crop_size": crop[1], "cd_pixels": int(mask.sum()), "budget_s": budget_s, "reference_spp": reference_spp,
           "reference_seconds": ref_seconds, "modes": {}}
    for mode in modes:
        sc = load_cropped(mi, spec, mode, crop)
        spp = _spp_for(mi, sc, budget_s)
        image, seconds = timed_render(mi, sc, seed=2, spp=spp)
        e = errors(image, ref_a, ref_b, mask)
        at_budget = {"relative_rms_error": e["relative_rms_error"] * np.sqrt(seconds / budget_s),
                     "relative_mse": e["relative_mse"] * seconds / budget_s}
        out["modes"][mode] = {"spp": spp, "seconds": seconds, **e, "at_budget": at_budget}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", default="640x480")
    parser.add_argument("--budget", type=float, default=20.0, help="seconds per mode")
    parser.add_argument("--reference-spp", type=int, default=4096)
    args = parser.parse_args()
    w, h = (int(v) for v in args.resolution.split("x"))
    r = noise_at_equal_time("cornell_cd", (w, h), args.budget, args.reference_spp)
    print(f"[{r['variant']}] cornell_cd at {w}x{h}, CD crop {r['crop_size'][0]}x{r['crop_size'][1]} "
          f"({r['cd_pixels']} CD pixels); reference: 2 x {r['reference_spp']} spp improved "
          f"({r['reference_seconds']:.0f} s each, its own noise removed)")
    for mode, m in r["modes"].items():
        b = m["at_budget"]
        print(f"{mode:>9}: {m['spp']} spp in {m['seconds']:.1f} s; at {r['budget_s']:g} s: relative RMS error "
              f"{b['relative_rms_error']:.4f}, relative MSE {b['relative_mse']:.5f}")
    p, i = r["modes"]["paper"]["at_budget"], r["modes"]["improved"]["at_budget"]
    print(f"paper / improved at equal time: relative RMS error {p['relative_rms_error'] / i['relative_rms_error']:.2f}, "
          f"relative MSE {p['relative_mse'] / i['relative_mse']:.2f} (goal: error ratio >= 2)")


if __name__ == "__main__":
    main()

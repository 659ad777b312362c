"""How rendering accuracy is measured on a scene's diffractive elements.

Shared by ``workbench study render`` (renderer.render_study) and the benchmarks. The film is
cropped to the pixels whose primary ray hits a CD (or its polycarbonate top) or a
grating, so every sample is spent where the comparison is made. Two independent
references A and B give the reference's own noise: for an image I,
E|I - A|^2 = E|I - truth|^2 + E|A - truth|^2 and E|A - B|^2 = 2 E|A - truth|^2, so
|I - A|^2 - |A - B|^2 / 2 estimates I's error against the truth without the reference's
noise.

Two error measures, both standard: the relative RMS error (RMS of I - truth over the
mean of the truth), dominated by the brightest pixels, and the relative MSE of
[Rousselle 2011, Sec. 6] (mean over pixels of (I - truth)^2 / (truth^2 + eps), here
eps = 1e-2 times the mean squared truth), which weighs every pixel alike.
"""

from __future__ import annotations

import numpy as np

from workbench.core.errors import UserInputError
from workbench.core.timing import timed

RELMSE_EPS = 1e-2


ELEMENT_PREFIXES = ("cd", "grating")  # scene keys of diffractive elements (renderer.mitsuba_scene), CD tops included


def primary_hits(mi, scene):
    """Each film pixel's centre ray and what it hits first: (intersections, rays, (H, W))."""
    sensor = scene.sensors()[0]
    W, H = sensor.film().crop_size()
    y, x = np.mgrid[0:H, 0:W]
    pixels = mi.Point2f(((x + 0.5) / W).ravel().astype(np.float32), ((y + 0.5) / H).ravel().astype(np.float32))
    ray, _ = sensor.sample_ray(0.0, 0.5, pixels, mi.Point2f(0.5, 0.5))
    return scene.ray_intersect(ray), ray, (H, W)


def element_mask(mi, scene_d: dict) -> np.ndarray:
    """Pixels of the (uncropped) film whose primary ray hits a diffractive element (a CD,
    its polycarbonate top, a grating)."""
    sc = mi.load_dict(scene_d)
    si, _, (H, W) = primary_hits(mi, sc)
    hit = np.zeros(W * H, bool)
    for s in sc.shapes():
        if s.id().startswith(ELEMENT_PREFIXES):
            hit |= np.array(si.shape == mi.ShapePtr(s))
    return hit.reshape(H, W)


def element_crop(mi, spec, margin: int = 2) -> tuple[tuple[list[int], list[int]], np.ndarray]:
    """((offset, size) of the film region the scene's diffractive elements cover, their
    mask over that region). Raises UserInputError when the camera sees none."""
    # deferred: pulls in the RCWA core and cv2, and renderer.render_study (imported by `workbench --help`) imports this module
    from renderer.mitsuba_scene import scene_dict

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
    from renderer.mitsuba_scene import scene_dict  # deferred: as in element_crop

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

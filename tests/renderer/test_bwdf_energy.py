"""Energy: a lossless see-through grating under uniform illumination (a furnace).

Under uniform radiance the expected improved-mode weight for a camera direction is the
sum of DE * (n_c / n_l)^2 over every channel and order that sends light there; for a
lossless structure with equal indices on both sides that is 1 (reciprocity: it equals
R + T for incidence from the reversed camera direction). Asserted within 1 % (the issue's
bound; measured 0.3 %, the table's bilinear interpolation) over random directions from
both sides and random wavelengths. Paper mode's energy error is printed, not asserted:
measured about +3 % here (its cos(theta_i)/cos(theta_o) factor and the Delta test).
A smooth, thin, low-contrast grating keeps guided-mode resonances, which no 2-degree
table interpolates, out of this test.
"""

import numpy as np

import rcwa
from rcwa.table import build_table, settings_for

TOLERANCE_ENERGY = 0.01


def _furnace_energy(mi, path, mode, n=200_000, seed=0):
    import drjit as dr

    bsdf = mi.load_dict({"type": "bwdf", "filename": str(path), "mode": mode})
    rng = np.random.default_rng(seed)
    cos_t = rng.uniform(-1, 1, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    sin_t = np.sqrt(1 - cos_t**2)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t)
    si.wavelengths = mi.Spectrum(*[mi.Float(w) for w in rng.uniform(460, 640, (4, n))])
    bs, w = bsdf.sample(mi.BSDFContext(), si, mi.Float(rng.random(n)), mi.Point2f(0.5, 0.5))
    w = np.array(w)
    transmitted = np.array(bs.wo)[2] * cos_t < 0
    return float(w.mean()), float(transmitted.mean())


def test_lossless_see_through_grating_keeps_energy(mitsuba_variant, tmp_path):
    import mitsuba as mi

    from renderer.bwdf import register

    register()
    s = rcwa.Structure.from_dict({"period": [0.6], "superstrate": "air", "substrate": "air", "layers": [
        {"thickness": 0.08, "material": "air", "shapes": [{"material": {"n": 1.3}, "x": [0.0, 0.3]}]}]})
    st = settings_for(s, "draft", wavelengths="450:650:3", theta_step=2.0, phi_step=6.0, orders=21, keep=5, both_sides=True)
    build_table(s, st, tmp_path / "lossless.zarr", progress=False)
    improved, transmitted_share = _furnace_energy(mi, tmp_path / "lossless.zarr", "improved")
    paper, _ = _furnace_energy(mi, tmp_path / "lossless.zarr", "paper")
    print(f"furnace energy: improved {improved:.4f}, paper {paper:.4f} (paper mode error {paper - 1:+.2%})")
    assert abs(improved - 1.0) < TOLERANCE_ENERGY
    assert 0.5 < transmitted_share < 1.0  # most light goes through this nearly transparent grating, some reflects

"""Reduction to a known material, rendered: a table holding only order 0 of a flat
aluminium mirror renders the same image as Mitsuba's conductor with aluminium's n and k.

A mirror reflecting a lit diffuse wall: the mean radiance over the mirror's pixels must
agree within 4 standard errors (estimated from independent renders with different
seeds; fixed seeds, so the test is repeatable), and so must each of a few blocks of
pixels. Improved mode terminates secondary wavelengths, so its colour noise is higher
than the conductor's; the means must still agree (it is unbiased).
"""

import numpy as np

import rcwa
from rcwa.table import build_table, settings_for

SEEDS = range(6)
BLOCKS = 4
Z_LIMIT = 4.0


def _scene(mi, bsdf):
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 4},
        "sensor": {
            "type": "perspective", "fov": 40,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, -1.2, 1.2], target=[0, 0, 0], up=[0, 0, 1]),
            "film": {"type": "hdrfilm", "width": 48, "height": 48},
            "sampler": {"type": "independent", "sample_count": 16},
        },
        "mirror": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale([0.4, 0.4, 1.0]), "bsdf": bsdf},
        "wall": {"type": "rectangle", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.8, 0.5, 0.3]}},
                 "to_world": mi.ScalarTransform4f().translate([0, 1.0, 0.6]).rotate([1, 0, 0], 90).scale([2.0, 1.0, 1.0])},
        "light": {"type": "constant", "radiance": 1.0},
    })


def _renders(mi, bsdf):
    scene = _scene(mi, bsdf)
    return np.stack([np.array(mi.render(scene, seed=s)) for s in SEEDS])


def test_aluminium_table_matches_the_conductor(mitsuba_variant, tmp_path):
    import mitsuba as mi

    from renderer.bwdf import register

    register()
    mirror = rcwa.Structure.from_dict({"period": [1.0], "superstrate": "air", "substrate": "aluminum", "layers": []})
    st = settings_for(mirror, "draft", wavelengths="360:830:48", theta_step=1.0, phi_step=45.0, orders=1, keep=1)
    build_table(mirror, st, tmp_path / "al.zarr", progress=False)
    al = rcwa.structure.material_from_spec("aluminum")
    wl = np.arange(360.0, 831.0, 10.0)
    n = al.refractive_index(wl)
    spectrum = lambda values: {"type": "irregular", "wavelengths": ", ".join(f"{w:g}" for w in wl),  # noqa: E731
                                "values": ", ".join(f"{v:.6f}" for v in values)}
    conductor = {"type": "conductor", "eta": spectrum(n.real), "k": spectrum(n.imag)}
    ours = _renders(mi, {"type": "bwdf", "filename": str(tmp_path / "al.zarr")})
    theirs = _renders(mi, conductor)
    black = np.array(mi.render(_scene(mi, {"type": "diffuse", "reflectance": 0.0}), seed=0))
    mask = black.sum(-1) == 0  # the mirror's pixels: black when the mirror is black
    lum_ours = ours.sum(-1)[:, mask]
    lum_theirs = theirs.sum(-1)[:, mask]
    assert 200 < mask.sum() < mask.size / 2
    blocks = np.array_split(np.arange(mask.sum()), BLOCKS)
    for idx in [np.arange(mask.sum())] + blocks:
        a, b = lum_ours[:, idx].mean(axis=1), lum_theirs[:, idx].mean(axis=1)  # one mean per seed
        se = np.sqrt(a.var(ddof=1) / a.size + b.var(ddof=1) / b.size)
        assert abs(a.mean() - b.mean()) < Z_LIMIT * se + 1e-3 * b.mean(), (a.mean(), b.mean(), se)

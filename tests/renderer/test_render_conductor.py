"""Reduction to a known material, rendered: a table holding only order 0 of a flat
aluminium mirror renders the same image as Mitsuba's conductor with aluminium's n and k.

A mirror reflecting a lit diffuse wall: the mean radiance over the mirror's pixels must
agree, and so must each of a few blocks of pixels. Improved mode terminates secondary
wavelengths, so its colour noise is higher than the conductor's; the means must still
agree (it is unbiased).

Noise allowed (issue 23): only the renders' Monte Carlo noise (no photo, so no shot or read
noise). It is measured from the data: each side is rendered with len(SEEDS) seeds and the
standard error of each side's mean is the spread of its per-seed means (a mean of ~500
pixels x 16 spp: Gaussian to good accuracy). The difference over that standard error is
Student-t with Welch-Satterthwaite degrees of freedom (measured 48-57), so the bound is
t.isf(FALSE_ALARM / 2, dof) standard errors (6.1-6.3), plus 1e-3 of the mean for the
table's spectral interpolation against the conductor's. Comparisons: 5 (the whole mirror
and BLOCKS blocks; union bound): false alarms 5 x FALSE_ALARM = 5e-7 per run. Before
(6 seeds, 4 standard errors, about 7 degrees of freedom) a t-tail of 0.5 % per comparison
gave about 1 false alarm in 50 runs. Smallest defect caught: a 1 % bias in the table's
reflectance (the whole mirror's bound is 0.66 % of its mean; checked by scaling one side's
renders by 0.99, which fails the whole-mirror comparison by 1.7 x its bound).
"""

import numpy as np
from scipy import stats

import rcwa
from rcwa.table import build_table, settings_for

SEEDS = range(32)   # 32 renders a side: the standard error itself known to about 13 % (Welch dof ~50)
BLOCKS = 4
FALSE_ALARM = 1e-7  # per comparison (two-sided); 5 comparisons per run


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
        z_limit, se = _welch_limit(a, b)
        assert abs(a.mean() - b.mean()) < z_limit * se + 1e-3 * b.mean(), (a.mean(), b.mean(), se, z_limit)


def _welch_limit(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """The standard error of mean(a) - mean(b) from the per-seed spreads, and the Student-t
    bound (Welch-Satterthwaite degrees of freedom) that a difference of no bias exceeds
    with probability FALSE_ALARM."""
    va, vb = a.var(ddof=1) / a.size, b.var(ddof=1) / b.size
    dof = (va + vb) ** 2 / (va**2 / (a.size - 1) + vb**2 / (b.size - 1))
    return float(stats.t.isf(FALSE_ALARM / 2, dof)), float(np.sqrt(va + vb))

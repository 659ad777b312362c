"""The CD's grating vector is radial at every hit point (renderer/bwdf.py, radial mapping).

The built CD is a 256-segment annulus mesh (renderer/meshes.py); a triangle's dp/du is
radial only along one of its edges, up to 2 pi / 256 = 1.4 degrees off elsewhere, which
moves the CD's fringes (about 0.2 px at 640 x 480). The plugin takes the radial direction
from the hit point and the CD's centre instead, which the builder passes from the scene.

Observed from the outside: a diffracted order changes the tangential wave vector along the
grating vector only (Lange et al. 2021, Eq. 2), so for every diffracted sample the
tangential part of wi + wo (local frame) lies along the grating vector. At random hit
points of rays cast at the built, tilted CD of cornell_cd_view2, that direction must be
the hit point's radial direction (hit point minus the scene's centre, in the tangent
plane) within TOLERANCE_RADIAL_RAD = 1e-5 rad: float32 directions (|wi + wo|_t >= 0.1,
so 1e-7 round-off gives about 1e-6 rad) and float32 hit points (0.5 m coordinates, 6e-8 m
steps, 1e-5 rad at the 7.5 mm hole's edge is the worst case). Measured: 5.4e-7 rad; the old
per-triangle dp/du axis failed it at 2.4e-2 rad (1.40 degrees).
"""

import math

import numpy as np
import pytest

TOLERANCE_RADIAL_RAD = 1e-5
POINTS = 4000
MIN_TANGENTIAL = 0.1  # |wi + wo|_t of a diffracted order here is >= 0.15 (lambda / (n Lambda), n = 1.59)


@pytest.fixture(scope="module")
def built_cd(mitsuba_variant, cd_table):
    """cornell_cd_view2 built by renderer.mitsuba_scene with the session's CD table and no top
    (rays reach the grating directly): the loaded scene and the CD's spec."""
    import mitsuba as mi

    from renderer.mitsuba_scene import scene_dict
    from renderer.scene import load_scene, parse_scene

    builtin = load_scene("cornell_cd_view2")
    text = builtin.text.replace('table = { preset = "draft" }', f'table = {{ path = "{cd_table.path}" }}')
    text = text.replace("top_surface = true", "top_surface = false")
    spec = parse_scene(text, source=builtin.source, base_dir=None)
    scene, _ = scene_dict(mi, spec, spp=1)
    return mi.load_dict(scene), spec.cds[0]


def _hits(mi, scene, cd, rng):
    """Rays cast straight at random points of the CD's annulus (uniform in area)."""
    from renderer.placement import frame_to

    R = frame_to(cd.normal, cd.rotation_deg)
    r = np.sqrt(rng.uniform(cd.inner_radius**2, cd.outer_radius**2, POINTS))
    a = rng.uniform(0, 2 * math.pi, POINTS)
    points = np.asarray(cd.center) + (R @ np.stack([r * np.cos(a), r * np.sin(a), np.zeros(POINTS)])).T
    tilt = (R @ np.stack([0.3 * np.cos(2 * a), 0.3 * np.sin(2 * a), np.ones(POINTS)])).T  # off the normal
    direction = -tilt / np.linalg.norm(tilt, axis=1, keepdims=True)
    origin = points - 0.02 * direction
    ray = mi.Ray3f(mi.Point3f(*origin.T.astype(np.float32)), mi.Vector3f(*direction.T.astype(np.float32)))
    return scene.ray_intersect(ray)


def test_grating_vector_is_radial_at_every_hit_point(built_cd):
    import mitsuba as mi

    from renderer.bwdf import GratingBWDF

    scene, cd = built_cd
    rng = np.random.default_rng(5)
    si = _hits(mi, scene, cd, rng)
    bwdf = next(s.bsdf() for s in scene.shapes() if isinstance(s.bsdf(), GratingBWDF))
    assert np.all(np.array(si.is_valid())), "every ray must hit the CD"
    si.wavelengths = mi.Spectrum(450.0, 520.0, 600.0, 680.0)
    bs, weight = bwdf.sample(mi.BSDFContext(), si, mi.Float(rng.random(POINTS).astype(np.float32)), mi.Point2f(0.5, 0.5))
    wi, wo = np.array(si.wi), np.array(bs.wo)
    tangential = (wi + wo)[:2]
    frame = [np.array(v, dtype=float) for v in (si.sh_frame.s, si.sh_frame.t)]
    outward = np.array(si.p, dtype=float) - np.asarray(cd.center)[:, None]
    radial = np.stack([np.sum(outward * f, axis=0) for f in frame])
    diffracted = (np.array(bs.pdf) > 0) & (np.linalg.norm(tangential, axis=0) > MIN_TANGENTIAL)
    assert diffracted.sum() > POINTS // 4, diffracted.sum()
    t, q = tangential[:, diffracted], radial[:, diffracted]
    sine = np.abs(t[0] * q[1] - t[1] * q[0]) / (np.linalg.norm(t, axis=0) * np.linalg.norm(q, axis=0))
    assert sine.max() < TOLERANCE_RADIAL_RAD, (sine.max(), np.degrees(sine.max()))


def test_builder_passes_the_cd_centre(built_cd):
    """The centre the plugin holds is the scene's (mi.traverse shows it)."""
    import mitsuba as mi

    scene, cd = built_cd
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("bsdf.center"))
    assert np.allclose(np.array(params[key]).ravel(), cd.center, atol=1e-7)

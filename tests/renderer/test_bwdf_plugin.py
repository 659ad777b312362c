"""The BWDF behaves as a Mitsuba plugin (renderer/bwdf.py, GratingBWDF).

* ``mi.traverse`` exposes exactly the settings that change the output in the configured
  mode and mapping (uniform share, Delta, grating angle, the radial mapping's centre); a value changed in place gives
  the samples of an instance built with it (1e-6: float32 round-off of the same
  arithmetic), out-of-range values are refused on ``update``.
* ``to_string`` names every setting; the class docstring's example runs.
* ``BSDFContext`` is honoured. A disabled component (reflection 0, transmission 1) is never
  sampled; paper mode's choice over the enabled one is uniform (chi-square, p > 1e-8,
  fixed seed: 2 components, 2e-8 false alarms per run, issue 23; it was 2e-3 at 1e-3); and the expected
  weight per wavelength with reflection alone plus that
  with transmission alone equals that with both (the estimator stays unbiased per
  component). Importance transport differs from radiance transport only on transmitted
  lobes, by the n^2 law's (n_cam / n_light)^2: sample by sample in paper mode (1e-5,
  float32), per direction in expectation in improved mode.

Expectations are taken over a stratified first random number (one sample per stratum, the
second number unused by delta lobes): the mean over STRATA strata of a function that is
constant between the few lobe boundaries in [0, 1) misses at most one stratum's weight per
boundary, under TOLERANCE_STRATIFIED relative here (the largest weight, 4 DE / p, is under
100 DE for these tables' lobe probabilities).
"""

import math
import textwrap

import numpy as np
import pytest
from scipy.stats import chisquare

import rcwa
from rcwa.table import build_table, settings_for

P_MIN = 1e-8  # a chi-square p-value under this fails: the false-alarm rate per comparison (issue 23)
WAVELENGTHS = (460.0, 520.0, 580.0, 640.0)
SUBSTRATE_INDEX = 1.5
STRATA = 200_000
TOLERANCE_STRATIFIED = 2e-3
TOLERANCE_IN_PLACE = 1e-6
TOLERANCE_N2 = 1e-5
# Camera directions above (superstrate, air) and below (substrate, n = 1.5); off the
# table's grid lines, away from grazing.
CAMERAS = ((0.31, 0.17, math.sqrt(1 - 0.31**2 - 0.17**2)), (-0.22, 0.28, -math.sqrt(1 - 0.22**2 - 0.28**2)))


@pytest.fixture(scope="module")
def see_through_table(mitsuba_variant, tmp_path_factory):
    """A weak dielectric grating on glass: reflects and transmits, different indices on
    the two sides (so the n^2 law is not 1)."""
    s = rcwa.Structure.from_dict({"period": [0.8], "superstrate": "air", "substrate": {"n": SUBSTRATE_INDEX},
                                  "layers": [{"thickness": 0.1, "material": "air",
                                              "shapes": [{"material": {"n": SUBSTRATE_INDEX}, "x": [0.0, 0.4]}]}]})
    st = settings_for(s, "draft", wavelengths="440:660:3", theta_step=10.0, phi_step=30.0, orders=11, keep=5,
                      both_sides=True)
    path = tmp_path_factory.mktemp("tables") / "see_through.zarr"
    build_table(s, st, path, progress=False)
    return path


def _load(path, **props):
    import mitsuba as mi

    from renderer.bwdf import register

    register()
    return mi.load_dict({"type": "bwdf", "filename": str(path), **props})


def _ctx(mode="radiance", flags=None, component=None):
    import mitsuba as mi

    transport = mi.TransportMode.Radiance if mode == "radiance" else mi.TransportMode.Importance
    ctx = mi.BSDFContext(transport, mi.BSDFFlags.All if flags is None else flags)
    if component is not None:
        ctx.component = component
    return ctx


def _sample(bsdf, wi, u1, ctx=None):
    """(wo, weight, pdf, sampled component) as numpy arrays, for one camera direction."""
    import drjit as dr
    import mitsuba as mi

    n = len(u1)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(*(float(c) for c in wi))
    si.wavelengths = mi.Spectrum(*WAVELENGTHS)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))  # hit point at the origin, in the xy-plane
    bs, w = bsdf.sample(ctx or _ctx(), si, mi.Float(np.asarray(u1, dtype=np.float32)), mi.Point2f(0.5, 0.5))
    return np.array(bs.wo), np.array(w), np.array(bs.pdf), np.array(bs.sampled_component)


def _stratified():
    return (np.arange(STRATA) + 0.5) / STRATA


def _per_direction(wo, w, pdf):
    """Expected weight (per wavelength) carried to each sampled direction: {direction: (4,)}."""
    valid = pdf > 0
    keys, group = np.unique(np.round(wo[:, valid].T, 4), axis=0, return_inverse=True)
    sums = np.stack([np.bincount(group.ravel(), weights=lane, minlength=len(keys)) for lane in w[:, valid]], axis=1)
    return {tuple(key): total / wo.shape[1] for key, total in zip(keys, sums, strict=True)}


# ---------------------------------------------------------------- parameters


@pytest.mark.parametrize("props, exposed", [
    ({"mapping": "radial", "center": [0.1, 0.2, 0.3]}, {"uniform_share", "center"}),
    ({}, {"uniform_share", "grating_angle"}),
    ({"mode": "paper"}, {"delta", "grating_angle"}),
    ({"mode": "paper", "mapping": "radial", "center": [0.1, 0.2, 0.3]}, {"delta", "center"}),
])
def test_traverse_exposes_what_changes_the_output(mitsuba_variant, cd_table, props, exposed):
    import mitsuba as mi

    assert set(mi.traverse(_load(cd_table.path, **props)).keys()) == exposed


@pytest.mark.parametrize("props, key, value", [
    ({}, "uniform_share", 0.15),
    ({"mode": "paper"}, "delta", 0.3),
    ({}, "grating_angle", 37.0),
    ({"mapping": "radial", "center": [0.0, 0.0, 0.0]}, "center", [0.02, -0.01, 0.0]),
])
def test_changed_in_place_equals_built_fresh(mitsuba_variant, cd_table, props, key, value):
    import mitsuba as mi

    rng = np.random.default_rng(11)
    u1 = rng.random(4096)
    wi = (0.45, -0.2, math.sqrt(1 - 0.45**2 - 0.2**2))
    bsdf = _load(cd_table.path, **props)
    before = _sample(bsdf, wi, u1)
    params = mi.traverse(bsdf)
    params[key] = mi.Point3f(*value) if key == "center" else value
    params.update()
    changed = _sample(bsdf, wi, u1)
    fresh = _sample(_load(cd_table.path, **{**props, key: value}), wi, u1)
    for a, b in zip(changed, fresh, strict=True):
        np.testing.assert_allclose(a, b, atol=TOLERANCE_IN_PLACE)
    assert not np.allclose(before[1], changed[1])  # the setting does change the output


@pytest.mark.parametrize("props, key, value, message", [
    ({}, "uniform_share", 1.5, "'uniform_share' must be within"),
    ({"mode": "paper"}, "delta", 0.0, "'delta' must be within"),
    ({"mode": "paper"}, "delta", 0.7, "'delta' must be within"),
    ({}, "grating_angle", math.inf, "'grating_angle' must be a finite angle"),
    ({"mapping": "radial", "center": [0.0, 0.0, 0.0]}, "center", [0.0, math.nan, 0.0], "'center' must be a point"),
])
def test_out_of_range_changes_are_refused(mitsuba_variant, cd_table, props, key, value, message):
    import mitsuba as mi

    params = mi.traverse(_load(cd_table.path, **props))
    params[key] = mi.Point3f(*value) if key == "center" else value
    with pytest.raises(ValueError, match=message):
        params.update()


def test_to_string_names_every_setting(see_through_table):
    import mitsuba as mi

    bsdf = _load(see_through_table, mode="paper", delta=0.1, grating_angle=12.5)
    text = str(bsdf)
    for expected in (str(see_through_table), 'mode = "paper"', 'mapping = "constant"', "grating_angle = 12.5 deg",
                     "uniform_share = 0.5 (unused: paper mode)", "delta = 0.1", "[reflection, transmission]",
                     "period_um = [0.8]", "(-2, 0), (-1, 0), (0, 0), (1, 0), (2, 0)", "wavelengths_nm = 440-660",
                     "superstrate air", "center = [0, 0, 0] (unused: constant mapping)",
                     "superstrate_index = 0 (the table's n(lambda))"):
        assert expected in text, (expected, text)
    params = mi.traverse(bsdf)
    params["delta"] = 0.25
    params.update()
    assert "delta = 0.25" in str(bsdf)
    radial = str(_load(see_through_table, mapping="radial", center=[0.1, 0.2, 0.3]))
    assert "center = [0.1, 0.2, 0.3]\n" in radial + "\n" or "center = [0.1, 0.2, 0.3]," in radial, radial
    assert "grating_angle = 0 deg (unused: radial mapping)" in radial


def test_docstring_example_runs(mitsuba_variant, cd_table, capsys):
    from renderer.bwdf import GratingBWDF

    example = textwrap.dedent(GratingBWDF.__doc__.split("Example::", 1)[1])
    assert '"cd.zarr"' in example
    exec(example.replace('"cd.zarr"', repr(str(cd_table.path))), {})  # noqa: S102 - our own docstring
    assert "uniform_share = 0.3" in capsys.readouterr().out


# ---------------------------------------------------------------- BSDFContext


@pytest.mark.parametrize("mode", ["improved", "paper"])
@pytest.mark.parametrize("wi", CAMERAS)
def test_disabled_components_are_never_sampled(see_through_table, mode, wi):
    import mitsuba as mi

    bsdf = _load(see_through_table, mode=mode)
    u1 = _stratified()
    flags = mi.BSDFFlags
    only_r = _sample(bsdf, wi, u1, _ctx(flags=flags.DeltaReflection))
    only_t = _sample(bsdf, wi, u1, _ctx(flags=flags.DeltaTransmission))
    by_index = _sample(bsdf, wi, u1, _ctx(component=1))
    neither = _sample(bsdf, wi, u1, _ctx(flags=flags.Diffuse))
    both = _sample(bsdf, wi, u1)
    for (wo, w, pdf, comp), reflected, component in ((only_r, True, 0), (only_t, False, 1), (by_index, False, 1)):
        valid = pdf > 0
        assert valid.mean() > 0.2  # most of the enabled lobes propagate here
        assert np.all((wo[2, valid] * wi[2] > 0) == reflected) and np.all(comp[valid] == component)
        assert np.all(w[:, ~valid] == 0)
    assert np.all(neither[2] == 0) and np.all(neither[1] == 0)
    # Unbiased per component: E[w | R only] + E[w | T only] = E[w | both], per wavelength.
    np.testing.assert_allclose(only_r[1].mean(axis=1) + only_t[1].mean(axis=1), both[1].mean(axis=1),
                               rtol=TOLERANCE_STRATIFIED)


def test_paper_mode_chooses_uniformly_within_the_enabled_component(see_through_table):
    import mitsuba as mi

    bsdf = _load(see_through_table, mode="paper")
    wi = CAMERAS[0]
    rng = np.random.default_rng(5)
    n = 100_000
    hero = 1  # u1 in [0.25, 0.5): the 520 nm wavelength leads
    u1 = (hero + rng.random(n)) / 4
    for flags, side in ((mi.BSDFFlags.DeltaReflection, 1.0), (mi.BSDFFlags.DeltaTransmission, -1.0)):
        wo, _, pdf, _ = _sample(bsdf, wi, u1, _ctx(flags=flags))
        valid = pdf > 0
        n_light = 1.0 if side > 0 else SUBSTRATE_INDEX
        # The order each direction came from, by Eq. 2: m = (k_inc - k_o) Lambda / lambda.
        orders = np.rint((-n_light * wo[0, valid] - wi[0]) * 800.0 / WAVELENGTHS[hero]).astype(int)
        kept, counts = np.unique(orders, return_counts=True)
        assert set(kept) <= {-2, -1, 0, 1, 2} and len(kept) >= 3
        assert chisquare(counts).pvalue > P_MIN  # uniform over the propagating kept orders
        # Each of the 5 kept orders takes 1/5 of the samples; the rest do not propagate.
        assert (~valid).sum() == pytest.approx(n * (5 - len(kept)) / 5, rel=0.05, abs=50)


@pytest.mark.parametrize("wi", CAMERAS)
def test_importance_transport_drops_only_the_n2_factor(see_through_table, wi):
    above = wi[2] > 0
    n_cam, n_light = (1.0, SUBSTRATE_INDEX) if above else (SUBSTRATE_INDEX, 1.0)
    n2 = (n_cam / n_light) ** 2
    u1 = _stratified()
    # Paper mode: the same choices in both transports; sample by sample.
    paper = _load(see_through_table, mode="paper")
    wo_r, w_r, pdf_r, _ = _sample(paper, wi, u1, _ctx("radiance"))
    wo_i, w_i, pdf_i, _ = _sample(paper, wi, u1, _ctx("importance"))
    assert np.array_equal(wo_r, wo_i) and np.array_equal(pdf_r, pdf_i)
    transmitted = wo_r[2] * wi[2] < 0
    assert transmitted.any() and (~transmitted).any()
    np.testing.assert_array_equal(w_r[:, ~transmitted], w_i[:, ~transmitted])
    np.testing.assert_allclose(w_r[:, transmitted], n2 * w_i[:, transmitted], rtol=TOLERANCE_N2)
    # Improved mode: its choice follows the transported quantity, so compare per direction.
    improved = _load(see_through_table)
    rad = _per_direction(*_sample(improved, wi, u1, _ctx("radiance"))[:3])
    imp = _per_direction(*_sample(improved, wi, u1, _ctx("importance"))[:3])
    assert rad.keys() == imp.keys()
    for direction, value in rad.items():
        factor = n2 if direction[2] * wi[2] < 0 else 1.0
        np.testing.assert_allclose(value, factor * imp[direction], rtol=TOLERANCE_STRATIFIED, atol=1e-7)

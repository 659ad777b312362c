"""`workbench render --target report`: each region sampled to what the report measures there
(renderer.render_target). Two renders with different seeds must differ by what their stated
noise says; a killed render resumes to the same bytes; the crop covers the CD's pixels.

Renders are small (96 x 72) and the CD's cap lowered to 256 spp, to keep them fast: what is
tested is that the noise a render states is the noise it has, whatever it reached.
"""

import json

import numpy as np
import pytest

from renderer import render_target
from renderer.render import render, summary, variance_path, with_resolution
from renderer.render_target import State, Target, Window, target_settings
from renderer.scene import load_scene
from workbench.cli import main

SMALL = dict(resolution=(96, 72), progress=False, target="report")
CD_CAP = 256
# Two independent renders differ per pixel by var_a + var_b. Pooled over the CD's ~190 pixels (3 channels, neighbours
# shared through the warp: ~100 independent values) the ratio's spread is ~0.15; fireflies make it heavy-tailed
# (the fixed renders' own test pools 6 pairs for 0.7-1.4), so one pair is held to a factor of 2 either way.
CD_RATIO_BOUNDS = (0.5, 2.0)
Z_REGION = 5.0  # the report's own bar for a region's mean (reports.compare.regions.Z_CONSISTENT)
Z_SCALE = 4.0  # one Gaussian draw beyond 4 sigma: 6e-5


@pytest.fixture()
def low_cap(monkeypatch):
    monkeypatch.setitem(render_target.CAP_SPP, "draft", CD_CAP)


def _exr(path):
    import mitsuba as mi

    return np.array(mi.Bitmap(str(path)), dtype=np.float64)


def _masks():
    from renderer.regions import region_masks

    return region_masks(with_resolution(load_scene("cornell_cd"), SMALL["resolution"]))


def test_two_seeds_differ_by_the_noise_the_renders_state(mitsuba_variant, tmp_path, low_cap):
    """Per region, the two renders' means differ within Z_REGION of their stated noise (the
    variance EXRs, as the report's region test reads them); over the CD, where the crop's
    passes merge with the frame's, the summed squared difference matches the summed
    variances; the walls' photometric scale between the two is within Z_SCALE of the
    scale noise the sidecars state."""
    images, variances, infos = [], [], []
    for seed in (0, 1):
        out = tmp_path / f"s{seed}.exr"
        infos.append(render("cornell_cd", out, seed=seed, **SMALL))
        images.append(_exr(out))
        variances.append(_exr(variance_path(out)))
    masks = _masks()
    for info in infos:
        cd = info["target"]["regions"]["cd"]
        assert cd["spp"][0] > info["target"]["frame_spp"] >= render_target.FLOOR_SPP  # the CD got its own samples
        assert info["target"]["crop"] is not None and info["target"]["walls"]["met"]
        assert info["target"]["regions"]["wall_back"]["spp"] == [render_target.FLOOR_SPP] * 2
    diff, var = images[0] - images[1], variances[0] + variances[1]
    for name, mask in masks.items():
        if mask.sum() >= 100:
            z = diff[mask].sum(axis=1).mean() / np.sqrt(var[mask].sum() / mask.sum() ** 2)
            assert abs(z) <= Z_REGION, (name, z)
    cd = masks["cd"]
    ratio = float(np.sum(diff[cd] ** 2) / np.sum(var[cd]))
    assert CD_RATIO_BOUNDS[0] < ratio < CD_RATIO_BOUNDS[1], ratio
    walls = render_target._eroded(masks["wall_left"] | masks["wall_right"] | masks["wall_back"], 1)
    scale = float(np.median(images[0].sum(axis=2)[walls] / images[1].sum(axis=2)[walls]))
    stated = np.hypot(*(info["target"]["walls"]["scale_relative_std"] for info in infos))
    assert abs(scale - 1) <= Z_SCALE * stated, (scale, stated)


def test_a_killed_targeted_render_resumes_to_the_same_bytes(mitsuba_variant, tmp_path, low_cap, monkeypatch):
    """Killed after its fifth saved pass (inside the CD's crop), the same command finishes it:
    the EXR, the variance and the decisions (every check) equal the uninterrupted render's. It
    replaced another render with --force; carrying on needs no --force again."""
    clean = render("cornell_cd", tmp_path / "clean.exr", **SMALL)
    render("cornell_cd", tmp_path / "r.exr", spp=4, resolution=(48, 36), progress=False)  # another render there
    save, calls = State.save, []

    def save_then_stop(self, path):
        save(self, path)
        calls.append(1)
        if len(calls) == 6:  # four frame passes, the frame's check, one crop pass
            raise KeyboardInterrupt

    monkeypatch.setattr(State, "save", save_then_stop)
    with pytest.raises(KeyboardInterrupt):
        render("cornell_cd", tmp_path / "r.exr", force=True, **SMALL)
    monkeypatch.setattr(State, "save", save)
    assert (tmp_path / "r.exr.partial.npz").is_file() and (tmp_path / "r.exr.partial.crop.npz").is_file()
    info = render("cornell_cd", tmp_path / "r.exr", **SMALL)
    assert info["resumed_passes"] == 5 and "resumed after 5" in summary(info)
    assert not list(tmp_path.glob("r.exr.partial*"))  # the frame's and the crop's saved sums removed
    assert np.array_equal(_exr(tmp_path / "r.exr"), _exr(tmp_path / "clean.exr"))
    assert np.array_equal(_exr(variance_path(tmp_path / "r.exr")), _exr(variance_path(tmp_path / "clean.exr")))
    assert info["target"]["checks"] == clean["target"]["checks"]
    sidecar = json.loads((tmp_path / "r.json").read_text())
    assert sidecar["target"]["regions"]["cd"]["spp"] == clean["target"]["regions"]["cd"]["spp"]
    assert "target report" in summary(info)


def test_the_crop_covers_every_pixel_the_warp_reads_for_the_cd(mitsuba_variant):
    """An image that is 1 inside the crop window and 0 outside, warped, is 1 at every CD pixel:
    the CD's image pixels read only plan pixels that the crop renders."""
    spec = with_resolution(load_scene("cornell_cd"), SMALL["resolution"])
    plan = spec.camera.model.pinhole_plan()
    masks = _masks()
    target = Target.build(spec.camera.model, plan, masks, target_settings("draft", 256))
    assert target.window is not None
    inside = np.zeros((plan.height, plan.width), np.float32)
    inside[target.window.slices] = 1.0
    warped = spec.camera.model.warp(inside, plan)
    assert np.all(warped[masks["cd"]] == 1.0)  # bilinear weights of ones sum to exactly one in float32
    assert target.window.width * target.window.height < 0.2 * plan.width * plan.height  # a crop, not the frame


def test_passes_of_unequal_size_merge_to_an_unbiased_variance():
    """The merged variance of the mean (weighted one-way ANOVA, renderer.render_target) averages
    to sigma^2 / N over many draws, for frame passes of one unit and crop passes of four."""
    rng = np.random.default_rng(1)
    window = Window(0, 0, 50, 50)
    sigma2, draws = 4.0, 400
    estimates = []
    for _ in range(draws):
        state = State("k")
        for _ in range(4):
            state.add("frame", rng.normal(1.0, np.sqrt(sigma2), (50, 50, 3)))
        for _ in range(3):
            state.add("crop", rng.normal(1.0, np.sqrt(sigma2 / 4), (50, 50, 3)))  # a pass of 4 units: variance / 4
        _mean, var, units = state.merged(window, weight=4)
        estimates.append(var[..., :3].mean())
    assert units[0, 0] == 16
    # 7 passes: 6 degrees of freedom per pixel, 7500 values a draw, 400 draws: the mean's relative std ~ 3e-4
    assert np.mean(estimates) == pytest.approx(sigma2 / 16, rel=0.01)


def test_the_targets_constants_follow_the_report():
    """The floor is the region test's trusted spp, the edge goal a third of the report's edge rule, and the
    command line's choice the renderer's list (kept apart so that `workbench --help` does not import the renderer)."""
    from reports.compare.regions import TRUSTED_SPP
    from reports.fringes.band_edges import EDGE_SIGMA_MAX_PX
    from workbench.commands import render as command

    assert render_target.FLOOR_SPP == TRUSTED_SPP
    assert render_target.EDGE_SIGMA_PX == pytest.approx(EDGE_SIGMA_MAX_PX / 3, abs=0.02)
    assert command.TARGETS == render_target.TARGETS
    assert render_target.FLOOR_SPP % render_target.PASS_SPP == 0 and render_target.FLOOR_SPP // render_target.PASS_SPP >= 4


def test_target_and_spp_together_are_refused(capsys):
    assert main(["render", "cornell_cd", "--out", "x.exr", "--target", "report", "--spp", "8", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "--spp" in err and "Traceback" not in err


def test_verify_renders_to_the_target_unless_spp_is_given():
    """verify's presets render targeted; --spp N is the fixed render of N samples everywhere."""
    from workbench.verify_run import VerifySettings

    assert VerifySettings().render_target == "report" and VerifySettings(preset="paper").render_target == "report"
    fixed = VerifySettings(spp=4)
    assert fixed.render_target is None and fixed.render_spp == 4 and fixed.to_json()["render_target"] is None


def _shifted_ratio(a, va, b, vb, dx: int) -> float:
    """sum (a - b)^2 / sum (va + vb) with ``a`` moved ``dx`` pixels right against ``b``."""
    if dx:
        a, va, b, vb = a[:, dx:], va[:, dx:], b[:, :-dx], vb[:, :-dx]
    return float(np.sum((a - b) ** 2) / np.sum(va + vb))


def test_the_crops_pixels_are_the_frames_pixels(mitsuba_variant):
    """Rendered through Mitsuba's film crop, the CD's window agrees with the same window of the
    full frame pixel for pixel within their noise (ratio near 1), and clearly not when shifted by
    one pixel (measured: 1.06 in place and 3.5 shifted here at 96 x 72; 0.89 and 7.3-8.1 at 160 x 120):
    the crop is merged in place. ~1250 values of 7 degrees of freedom: the in-place ratio's spread is
    ~0.05 plus fireflies, so (0.6, 1.6); a shift's edges add far more than 1."""
    import mitsuba as mi

    from renderer.mitsuba_scene import cropped_sensor, scene_dict

    spec = with_resolution(load_scene("cornell_cd"), SMALL["resolution"])
    scene_d, built = scene_dict(mi, spec, spp=32, plan=True, progress=False)
    window = Target.build(spec.camera.model, built["plan"], _masks(), target_settings("draft", 256)).window
    assert window is not None
    scene = mi.load_dict(scene_d)
    crop = mi.load_dict(cropped_sensor(scene_d["sensor"], (window.x, window.y), (window.width, window.height)))

    def mean_and_variance(sensor, seeds, where=(slice(None), slice(None))):
        images = np.array([np.array(mi.render(scene, sensor=sensor, seed=s))[where] for s in seeds], np.float64)
        return images.mean(axis=0), images.var(axis=0, ddof=1) / len(seeds)

    frame, frame_var = mean_and_variance(0, range(100, 108), window.slices)
    cropped, cropped_var = mean_and_variance(crop, range(200, 208))
    assert cropped.shape == frame.shape
    assert 0.6 < _shifted_ratio(cropped, cropped_var, frame, frame_var, 0) < 1.6
    assert _shifted_ratio(cropped, cropped_var, frame, frame_var, 1) > 2.0

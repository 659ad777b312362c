"""The render check's passes (calibration/pose/render_check.py): how many it renders is
decided by the noise measured between them.

The renderer is replaced by an exact image of the box (tests/calibration/test_pose.py's
rasterised_box, also the photo) times a known gain per pass, so that the scale's noise
between passes is known exactly: with gains 1 + a, 1 - a, 1 + a, ... the per-pass scales
are 1 / (1 +- a), and the rule's estimate (their standard deviation over sqrt(passes),
relative) is about a for 2 passes and a sqrt(4/3) / 2 = 0.58 a for 4 (to O(a^2)).
"""

from __future__ import annotations

import dataclasses
from typing import cast

import numpy as np
import pytest

import calibration.pose.render_check as check_module
from calibration.pose.edge_fit import PoseSettings, match_edges
from calibration.pose.edges import smoothed
from calibration.pose.photo import Photo
from calibration.pose.render_check import SCALE_NOISE, render_check
from calibration.pose.scene_model import scene_model
from renderer.render import with_resolution
from renderer.scene import load_scene
from tests.calibration.test_pose import _Photo, rasterised_box


class _Renderer:
    def set(self, **_changes) -> None:
        pass


@pytest.fixture(scope="module")
def box():
    spec = dataclasses.replace(with_resolution(load_scene("cornell_cd"), (320, 240)), cds=(), glass=())
    camera = spec.camera.model
    image = rasterised_box(spec, camera)
    model = scene_model(spec)
    settings = PoseSettings()
    match = match_edges(smoothed(image), model, camera, settings.fine_windows_px[-1], settings)
    return image, model, camera, match


def _run(box, monkeypatch, gain_step: float, render_spp: int, pose_noise=None):
    image, model, camera, match = box
    rendered: list[tuple[int, int]] = []

    def fake_pass(_renderer, spp: int, seed: int) -> np.ndarray:
        rendered.append((spp, seed))
        gain = 1.0 + gain_step * (1 if seed % 2 == 0 else -1)
        return np.repeat(image[..., None], 3, axis=2) * gain

    monkeypatch.setattr(check_module, "render_pass", fake_pass)
    settings = PoseSettings(render_spp=render_spp)
    result = render_check(_Renderer(), cast(Photo, _Photo(image)), model, camera, match, settings.fine_windows_px[-1], settings,
                          pose_noise)
    return result, rendered


def test_a_noiseless_render_stops_at_the_first_measurement(box, monkeypatch) -> None:
    result, rendered = _run(box, monkeypatch, 0.0, 64)
    assert rendered == [(4, 0), (4, 1)] and result.spp == 8
    assert result.scale == pytest.approx(1.0, abs=1e-6)  # photo and render are the same image
    image, _, _, match = box  # the same image: the render's edges are where the photo's are, to float32 round-off
    np.testing.assert_allclose(result.bias, match.offsets, atol=1e-4)


def test_passes_double_until_the_scale_noise_is_below_its_bound(box, monkeypatch) -> None:
    step = 1.5 * SCALE_NOISE  # 2 passes: 1.5 x the bound; 4 passes: 0.87 x
    result, rendered = _run(box, monkeypatch, step, 64)
    assert [seed for _, seed in rendered] == [0, 1, 2, 3] and result.spp == 16
    assert result.noise["8"]["scale_relative"] == pytest.approx(step, rel=0.01)
    assert result.noise["16"]["scale_relative"] == pytest.approx(step * np.sqrt(4 / 3) / 2, rel=0.01)
    assert result.scale == pytest.approx(1.0, rel=1e-5)  # gains +-a cancel in the merged render to O(a^2)


def test_the_pose_noise_decides_too_and_render_spp_caps_the_passes(box, monkeypatch) -> None:
    calls = []

    def never_enough(passes, _check):
        calls.append(len(passes))
        return {"rotation_deg": 1.0}, False

    result, rendered = _run(box, monkeypatch, 0.0, 32, never_enough)
    assert calls == [2, 4] and len(rendered) == 8 and result.spp == 32  # not measured at the cap: nothing to decide
    assert result.noise["16"]["rotation_deg"] == 1.0 and "rotation_deg" not in result.noise["32"]


def test_one_fixed_render_when_the_passes_would_exceed_render_spp(box, monkeypatch) -> None:
    result, rendered = _run(box, monkeypatch, 0.0, 6)  # fewer than two passes of 4
    assert rendered == [(6, 0)] and result.spp == 6 and result.noise == {}

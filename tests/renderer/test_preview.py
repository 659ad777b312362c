"""The render's PNG preview (renderer.preview; issue 49, item 5): white-balanced to the
scene's light, at a white level a series of renders can share.

Bars. The gains equal 1 / AsShotNeutral of datasets_synthetic.sensor (its own integration
of the same curves, written for the DNG tags) to 1e-3: each integrates on its own
wavelength grid (measured 5e-5 apart). The back wall's white paint is
neutral in this camera to 0.6 % but tinted by the red and green walls: balanced, its
R/G and B/G were measured 1.037 and 0.961 (tests/datasets_synthetic/test_synth.py), so
within 10 % of grey; unbalanced camera RGB reads it green (R/G about 0.7), which the test
requires too, so the balance is shown to matter."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from renderer.preview import white_balance
from renderer.scene import load_scene
from workbench.cli import main

GREY_TOLERANCE = 0.10
RENDER = ["--spp", "8", "--resolution", "80x60", "--quiet"]


def _linear_png(path: Path) -> np.ndarray:
    x = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)[..., ::-1].astype(float) / 255.0
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _exr(path: Path) -> np.ndarray:
    import OpenImageIO as oiio

    return oiio.ImageBuf(str(path)).get_pixels()[..., :3].astype(float)


def test_the_gains_are_the_inverse_of_the_dng_neutral() -> None:
    from datasets_synthetic.sensor import as_shot_neutral
    from renderer.spectra import camera_sensitivities, light_spectrum, on_common_grid

    spec = load_scene("cornell_cd")
    wl, curves = on_common_grid(camera_sensitivities(spec.camera.sensitivities))
    light_wl, light = light_spectrum(spec.light.spectrum)
    neutral = as_shot_neutral(wl, curves, np.interp(wl, light_wl, light, left=0.0, right=0.0))
    gains = white_balance(spec.light.spectrum, spec.camera.sensitivities)
    assert gains[1] == 1.0
    np.testing.assert_allclose(np.multiply(gains, neutral), 1.0, rtol=1e-3)


def test_the_back_wall_is_grey_and_a_shared_white_level_shows_exposure(tmp_path: Path, capsys) -> None:
    from renderer.regions import region_masks
    from renderer.render import with_resolution

    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    assert main(["render", "cornell_cd", "--out", str(a), *RENDER]) == 0
    wall = region_masks(with_resolution(load_scene("cornell_cd"), (80, 60)))["wall_back"]
    raw = _exr(a)[wall].mean(axis=0)
    shown = _linear_png(a.with_suffix(".png"))[wall].mean(axis=0)
    assert raw[0] / raw[1] < 0.8  # camera RGB: the white wall reads green
    assert abs(shown[0] / shown[1] - 1) < GREY_TOLERANCE and abs(shown[2] / shown[1] - 1) < GREY_TOLERANCE, shown
    level = json.loads(a.with_suffix(".json").read_text())["preview_settings"]["white_level"]

    dim = tmp_path / "dim.toml"
    text = load_scene("cornell_cd").text
    assert "\nexposure = 1.0\n" in text
    dim.write_text(text.replace("\nexposure = 1.0\n", "\nexposure = 0.25\n"))
    assert main(["render", str(dim), "--out", str(b), "--preview-like", str(a.with_suffix(".json")), *RENDER]) == 0
    settings = json.loads(b.with_suffix(".json").read_text())["preview_settings"]
    assert settings["white_level"] == level and settings["source"] == str(a.with_suffix(".json"))
    ratio = _linear_png(b.with_suffix(".png"))[wall].mean() / shown.mean()
    assert ratio == pytest.approx(0.25, rel=0.1)  # two stops darker on screen too (8-bit rounding, same samples)

    # the finished render served again with another white level: only its preview and sidecar change
    exr_bytes = b.read_bytes()
    assert main(["render", str(dim), "--out", str(b), "--preview-white", str(level / 4), *RENDER]) == 0
    assert "up to date" in capsys.readouterr().out and b.read_bytes() == exr_bytes
    assert json.loads(b.with_suffix(".json").read_text())["preview_settings"]["white_level"] == level / 4
    again = _linear_png(b.with_suffix(".png"))[wall].mean() / shown.mean()
    assert again == pytest.approx(1.0, rel=0.1)


def test_a_missing_reference_render_is_refused_in_one_line(tmp_path: Path, capsys) -> None:
    assert main(["render", "cornell_cd", "--out", str(tmp_path / "x.exr"), "--preview-like",
                 str(tmp_path / "none.json"), *RENDER]) == 2
    err = capsys.readouterr().err
    assert "none.json" in err and "no such render sidecar" in err and len(err.strip().splitlines()) == 1

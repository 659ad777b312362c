"""Response curves: analytic values, inversion and validation (renderer/response.py).

Tolerances: gamma is closed-form (1e-12); the sampled curve's inverse is a table lookup
on 4097 points (5e-4)."""

import numpy as np
import pytest

from renderer.response import ResponseCurve
from renderer.scene import load_scene, parse_scene
from workbench.core.errors import UserInputError


def test_gamma_and_its_inverse():
    r = ResponseCurve.from_spec({"gamma": 2.2})
    x = np.linspace(0, 1, 11)
    assert np.allclose(r.apply(x), x ** (1 / 2.2), atol=1e-12)
    assert np.allclose(r.invert(r.apply(x)), x, atol=1e-12)


def test_sampled_curve_is_monotone_and_invertible():
    pts = [[0.0, 0.0], [0.2, 0.45], [0.5, 0.75], [1.0, 1.0]]
    r = ResponseCurve.from_spec({"points": pts})
    x = np.linspace(0, 1, 101)
    y = r.apply(x)
    assert np.all(np.diff(y) >= 0) and np.allclose(r.apply([0.2, 0.5]), [0.45, 0.75])
    assert np.allclose(r.invert(y), x, atol=5e-4)


@pytest.mark.parametrize("spec", [{"gamma": -1}, {"points": [[0, 0], [0.5, 0.3], [0.4, 0.6], [1, 1]]},
                                  {"points": [[0.1, 0], [1, 1]]}, {"curve": 3}, "sigmoid"])
def test_bad_response_curves(spec):
    with pytest.raises(UserInputError, match="camera.response"):
        ResponseCurve.from_spec(spec)


def test_scene_camera_response_is_parsed():
    text = load_scene("cornell_cd").text.replace("exposure = 1.0", "exposure = 1.0\nresponse = { gamma = 2.4 }")
    scene = parse_scene(text, source="s.toml", base_dir=None)
    assert scene.camera.response.kind == "gamma" and scene.camera.response.gamma == 2.4

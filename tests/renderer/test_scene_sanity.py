"""Scene sanity when a scene loads (renderer/scene.py, renderer/camera_coverage.py; issue 45 item 6).

A scene that would render black or miss the box is refused with the field named and the box's
extent: a light outside the ceiling (y = 1.5 m in a 0.55 m or a 1 m box rendered all black,
0 non-zero pixels of 163 x 122), a CD, grating or glass object outside the box or through a wall,
a camera in a wall or looking away from the box, a CD or opaque grating whose front the light
cannot reach. `plan` and `render` refuse it with one `error:` line and exit 2, before anything
renders. A camera that sees little of the scene is legitimate: a warning, not a refusal. The
built-in scenes and the documented examples load without a warning. The default light follows
``box.size`` (a 1 m box gets its light 0.1 mm below its own ceiling) and stays bitwise the
measured one in the measured box.

Tolerances: positions are compared to 1e-12 m (round-off of a scale by 1.0 and of a mean);
every refused case sits at least 1 cm beyond the 1 mm slack the checks allow.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from renderer.scene import MM, box_scale, cornell_data, load_scene, parse_scene
from workbench.core.errors import UserInputError

BASE = load_scene("cornell_cd").text
GRATING = load_scene("grating2d_gold").text
ROUND_OFF_M = 1e-12
BIG_BOX = 'model = "cornell"\nsize = [1.0, 1.0, 1.0]'


def _refused(text: str) -> UserInputError:
    with pytest.raises(UserInputError) as info:
        parse_scene(text, source="bad.toml", base_dir=None)
    assert info.value.file == "bad.toml"
    return info.value


def _with_light(center: str, base: str = BASE) -> str:
    return base.replace("[light]\n", f"[light]\ncenter = {center}\n")


@pytest.mark.parametrize(("text", "field", "words"), [
    (_with_light("[0.278, 1.5, 0.28]"), "light.center", "0.5488"),                 # above the measured box's ceiling
    (_with_light("[0.5, 1.5, 0.5]", BASE.replace('model = "cornell"', BIG_BOX)), "light.center", "y 0.98 to 1"),
    (_with_light("[0.278, 0.30, 0.28]"), "light.center", "ceiling"),               # hanging in the middle of the box
    (_with_light("[0.52, 0.5487, 0.28]"), "light.center", "x 0 to 0.556"),          # its rectangle past the right wall
    (BASE.replace("[light]\n", "[light]\nsize = [0.7, 0.1]\n"), "light.size", "0.556"),
    (BASE.replace("center = [0.28, 0.023, 0.25]", "center = [0.28, 0.023, 0.70]"), "cd[0].center", "z 0 to 0.5592"),
    (BASE.replace("center = [0.28, 0.023, 0.25]", "center = [0.28, 0.005, 0.25]"), "cd[0].center", "the box's extent"),
    (BASE.replace("center = [0.17, 0.0201, 0.18]", "center = [-0.10, 0.0201, 0.18]"), "glass[0].center", "x 0 to 0.556"),
    (BASE.replace("center = [0.40, 0.0251, 0.16]", "center = [0.40, 0.0251, 0.55]"), "glass[1].center", "z 0 to 0.5592"),
    (GRATING.replace("center = [0.278, 0.16, 0.30]", "center = [0.278, 0.16, 0.60]"), "grating[0].center", "the box"),
    (BASE.replace("normal = [0.0, 0.9397, -0.3420]", "normal = [0.0, -1.0, 0.0]"), "cd[0].normal", "faces away"),
    (BASE.replace("target = [0.28, 0.05, 0.30]", "target = [0.278, 0.42, -1.5]"), "camera.look_at.target", "looks away"),
    (BASE.replace("origin = [0.278, 0.42, -0.55]", "origin = [0.278, 0.42, 0.70]"), "camera.look_at.origin", "wall"),
])
def test_a_scene_that_would_render_black_or_miss_the_box_is_refused(text: str, field: str, words: str) -> None:
    error = _refused(text)
    assert error.field == field and words in str(error), str(error)


def test_an_opaque_grating_facing_away_from_the_light_is_refused_a_see_through_one_is_not() -> None:
    """gold2d (blocks in air) transmits: lit from behind, its front shows the transmitted orders. The CD's
    structure on the same plate is opaque (aluminium substrate): no light reaches its front."""
    down = GRATING.replace("normal = [0.0, 0.0, -1.0]", "normal = [0.0, -1.0, 0.0]")
    assert parse_scene(down, source="ok.toml", base_dir=None).gratings[0].normal == (0.0, -1.0, 0.0)
    error = _refused(down.replace('structure = "gold2d"', 'structure = "cd"'))
    assert error.field == "grating[0].normal" and "faces away" in str(error)


def test_a_camera_given_as_a_matrix_that_looks_away_names_the_matrix() -> None:
    from calibration.pose.scene_file import fitted_scene_text  # how calibration writes a fitted camera

    spec = load_scene("cornell_cd")
    turned = spec.camera.model.world_to_camera.copy()
    turned[:3, :3] = np.diag([-1.0, 1.0, -1.0]) @ turned[:3, :3]   # half a turn about the camera's y axis
    turned[:3, 3] = np.diag([-1.0, 1.0, -1.0]) @ turned[:3, 3]      # about its own centre
    from dataclasses import replace

    text = fitted_scene_text(spec, replace(spec.camera.model, world_to_camera=turned), 1.0)
    error = _refused(text)
    assert error.field == "camera.world_to_camera" and "looks away" in str(error)


def test_a_camera_that_sees_little_of_the_scene_is_a_warning() -> None:
    """Looking past the box's left edge: 4 % of the image on the box, none of the CD."""
    text = BASE.replace("target = [0.28, 0.05, 0.30]", "target = [-0.3, 0.30, 0.0]")
    spec = parse_scene(text, source="aside.toml", base_dir=None)
    assert any("sees little of the box" in w for w in spec.warnings), spec.warnings
    assert any("none of the CDs" in w for w in spec.warnings), spec.warnings


@pytest.mark.parametrize("name", ["cornell_cd", "cornell_cd_view2", "grating2d_gold", "docs/examples/my_scene.toml",
                                  "docs/examples/fisheye_cd.toml"])
def test_the_built_in_and_documented_scenes_load_without_a_warning(name: str) -> None:
    root = Path(__file__).resolve().parents[2]
    spec = load_scene(name if "/" not in name else root / name)
    assert spec.warnings == ()


def test_the_default_light_follows_the_box_size() -> None:
    pts = np.asarray(cornell_data()["geometry"]["light"], float) * MM
    measured = load_scene("cornell_cd").light
    assert measured.center == tuple(float(c) for c in pts.mean(axis=0) - [0, 1e-4, 0])  # bitwise: the measured light
    assert measured.size == (float(np.ptp(pts[:, 0])), float(np.ptp(pts[:, 2])))
    big = parse_scene(BASE.replace('model = "cornell"', BIG_BOX), source="big.toml", base_dir=None)
    scale = box_scale(big.box)
    assert abs(big.light.center[1] - (1.0 - 1e-4)) < ROUND_OFF_M  # 0.1 mm below its own ceiling, as in the measured box
    np.testing.assert_allclose(big.light.center, pts.mean(axis=0) * scale - [0, 1e-4, 0], rtol=0, atol=ROUND_OFF_M)
    np.testing.assert_allclose(big.light.size, [np.ptp(pts[:, 0]) * scale[0], np.ptp(pts[:, 2]) * scale[2]], atol=ROUND_OFF_M)


def test_plan_and_render_refuse_before_anything_renders(tmp_path: Path, capsys) -> None:
    from workbench.cli import main

    scene = tmp_path / "light_outside.toml"
    scene.write_text(_with_light("[0.278, 1.5, 0.28]"))
    assert main(["plan", str(scene)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {scene}: field 'light.center'"), err
    assert main(["render", str(scene), "--out", str(tmp_path / "r.exr")]) == 2
    assert "light.center" in capsys.readouterr().err and not list(tmp_path.glob("r*"))


def test_plan_prints_the_warning_and_goes_on(tmp_path: Path, capsys) -> None:
    from workbench.cli import main

    scene = tmp_path / "aside.toml"
    scene.write_text(BASE.replace("target = [0.28, 0.05, 0.30]", "target = [-0.3, 0.30, 0.0]"))
    assert main(["plan", str(scene), "--json"]) == 0
    captured = capsys.readouterr()
    assert "warning: the camera sees little of the box" in captured.err and captured.out.lstrip().startswith("{")

"""reports/report.py through ``workbench report``: bad input gives clear messages, never a traceback.

The images here are small synthetic EXRs (the report does not care where pixels came
from); the calibration has the synthetic dataset's truth.json form. Tests that build
the scene (region masks) share the suite's table cache.
"""

import json

import numpy as np
import pytest

from renderer.render import with_resolution
from renderer.scene import load_scene
from workbench.cli import main

SIZE = (160, 120)


def _write_exr(path, image):
    import OpenImageIO as oiio

    out = oiio.ImageOutput.create(str(path))
    assert out is not None
    out.open(str(path), oiio.ImageSpec(image.shape[1], image.shape[0], 3, oiio.FLOAT))
    out.write_image(np.ascontiguousarray(image, np.float32))
    out.close()
    return path


def _calibration(path, camera, scene="cornell_cd_view2", photo="photo.exr"):
    path.write_text(json.dumps({"scene": scene, "camera": {
        "width": camera.width, "height": camera.height, "fx": camera.fx, "fy": camera.fy, "cx": camera.cx,
        "cy": camera.cy, "dist": list(camera.dist), "world_to_camera": {photo: camera.world_to_camera.tolist()}}}))
    return path


def _camera():
    return with_resolution(load_scene("cornell_cd_view2"), SIZE).camera.model


def _run(tmp_path, capsys, photo, render, calibration, scene="cornell_cd_view2"):
    code = main(["report", "--photo", str(photo), "--render", str(render), "--calibration", str(calibration),
                 "--scene", scene, "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return code, captured.out + captured.err


def _flat(size=SIZE, value=0.3, seed=0):
    rng = np.random.default_rng(seed)
    return (value + 0.01 * rng.standard_normal((size[1], size[0], 3))).astype(np.float32)


def test_photo_and_render_of_different_sizes(tmp_path, capsys):
    photo = _write_exr(tmp_path / "photo.exr", _flat())
    render = _write_exr(tmp_path / "render.exr", _flat((80, 60)))
    code, text = _run(tmp_path, capsys, photo, render, _calibration(tmp_path / "c.json", _camera()))
    assert code == 2 and "share one pixel grid" in text and "160 x 120" in text and "80 x 60" in text


def test_calibration_of_another_scene(tmp_path, capsys):
    photo = _write_exr(tmp_path / "photo.exr", _flat())
    render = _write_exr(tmp_path / "render.exr", _flat())
    code, text = _run(tmp_path, capsys, photo, render, _calibration(tmp_path / "c.json", _camera(), scene="cornell_cd"))
    assert code == 2 and "made for the scene 'cornell_cd'" in text


@pytest.mark.parametrize("content, words", [("{", "not a readable JSON"), ("{}", "no camera block"),
                                            ('{"camera": {"width": 160}}', "camera.height")])
def test_broken_calibration(tmp_path, capsys, content, words):
    photo = _write_exr(tmp_path / "photo.exr", _flat())
    render = _write_exr(tmp_path / "render.exr", _flat())
    (tmp_path / "c.json").write_text(content)
    code, text = _run(tmp_path, capsys, photo, render, tmp_path / "c.json")
    assert code == 2 and words in text


def test_jpeg_photo_is_refused_with_the_reason(tmp_path, capsys):
    (tmp_path / "photo.jpg").write_bytes(b"\xff\xd8\xff")
    render = _write_exr(tmp_path / "render.exr", _flat())
    code, text = _run(tmp_path, capsys, tmp_path / "photo.jpg", render, _calibration(tmp_path / "c.json", _camera()))
    assert code == 2 and "fitted response" in text


@pytest.mark.slow
def test_cd_out_of_view_still_reports_the_rest(tmp_path, capsys):
    from scipy.spatial.transform import Rotation

    camera = _camera()
    turn = Rotation.from_rotvec(np.radians([0.0, -40.0, 0.0])).as_matrix()  # toward the left wall, away from the CD
    pose = camera.world_to_camera.copy()
    pose[:3, :3], pose[:3, 3] = turn @ pose[:3, :3], turn @ pose[:3, 3]
    away = camera.__class__(camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy, camera.dist, pose)
    photo = _write_exr(tmp_path / "photo.exr", _flat())
    render = _write_exr(tmp_path / "render.exr", _flat(seed=1))
    code, text = _run(tmp_path, capsys, photo, render, _calibration(tmp_path / "c.json", away))
    assert code == 0, text
    assert "does not see the CD" in text
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["cd"]["status"] == "not in view" and report["metrics"]["per_region"]["all"]["pixels"] == SIZE[0] * SIZE[1]
    assert "does not see the CD" in (tmp_path / "out" / "report.html").read_text()


@pytest.mark.slow
def test_no_fringes_visible_and_script_in_names(tmp_path, capsys):
    """A photo without the CD's bands: the report is written and says so; a file name with
    <script> in it shows as text on the page."""
    name = "photo<script>alert(1)<.exr"
    photo = _write_exr(tmp_path / name, _flat())
    render = _write_exr(tmp_path / "render.exr", _flat(seed=1))
    code, text = _run(tmp_path, capsys, photo, render, _calibration(tmp_path / "c.json", _camera(), photo=name))
    assert code == 0, text
    assert "no fringes visible" in text
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["fringe_offset_px"]["count"] == 0
    page = (tmp_path / "out" / "report.html").read_text()
    assert "<script>alert(1)" not in page and "&lt;script&gt;alert(1)&lt;" in page
    assert (tmp_path / "out" / "fringes.csv").exists()

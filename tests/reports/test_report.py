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


def _write_jpeg(path, codes):
    import cv2

    assert cv2.imwrite(str(path), np.ascontiguousarray(codes[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, 100])
    return path


GAMMA = 2.2  # the test camera's response: value = irradiance ** (1 / GAMMA)


def _gamma_response():
    irradiance = np.linspace(0.0, 1.0, 65)
    return {"points": [[float(e), float(e ** (1 / GAMMA))] for e in irradiance]}


def test_jpeg_without_a_fitted_response_is_refused_with_the_reason(tmp_path, capsys):
    photo = _write_jpeg(tmp_path / "photo.jpg", np.full((SIZE[1], SIZE[0], 3), 128, np.uint8))
    render = _write_exr(tmp_path / "render.exr", _flat())
    code, text = _run(tmp_path, capsys, photo, render, _calibration(tmp_path / "c.json", _camera(), photo="photo.jpg"))
    assert code == 2 and "no response curve" in text and "--photo" in text


def test_damaged_jpeg_is_refused_naming_the_file(tmp_path, capsys):
    (tmp_path / "photo.jpg").write_bytes(b"\xff\xd8\xff")
    render = _write_exr(tmp_path / "render.exr", _flat())
    code, text = _run(tmp_path, capsys, tmp_path / "photo.jpg", render, _calibration(tmp_path / "c.json", _camera()))
    assert code == 2 and "photo.jpg" in text and "cannot be read" in text


def test_jpeg_is_linearised_through_the_calibrations_response(tmp_path):
    """calibration.raw.decode inverts the fitted response: a grey ramp encoded with gamma 2.2 comes back linear
    within 1.5 % of full scale (JPEG at quality 100 keeps codes within about 1 of 255; the inverse response's
    slope near 0.2 irradiance is about 0.5 / 255 per code; the 65-knot table interpolates within 0.3 %)."""
    from calibration.calibration_file import read_response
    from reports.compare import images

    linear = np.tile(np.linspace(0.05, 0.95, SIZE[0]), (SIZE[1], 1))
    codes = np.round(255 * linear ** (1 / GAMMA)).astype(np.uint8)
    photo_path = _write_jpeg(tmp_path / "photo.jpg", np.repeat(codes[..., None], 3, axis=2))
    calibration = _calibration(tmp_path / "c.json", _camera(), photo="photo.jpg")
    record = json.loads(calibration.read_text())
    calibration.write_text(json.dumps({**record, "response": _gamma_response()}))
    photo = images.read_photo(photo_path, read_response(calibration))
    assert photo.kind == "linear" and photo.channel is None
    assert np.max(np.abs(photo.rgb[..., 1] - linear)) < 0.015
    assert photo.decoding is not None and photo.decoding["response"] == "response"


def test_broken_response_in_the_calibration_names_file_and_field(tmp_path):
    from calibration.calibration_file import read_response
    from workbench.core.errors import UserInputError

    calibration = tmp_path / "c.json"
    calibration.write_text(json.dumps({"response": {"points": [[0, 0.5], [1, 0.2]]}}))
    with pytest.raises(UserInputError) as caught:
        read_response(calibration)
    assert "c.json" in str(caught.value) and "response" in str(caught.value)


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

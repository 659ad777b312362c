"""`workbench synth`: layout, truth, determinism and bad input."""

import json

import numpy as np
import pytest
import rawpy

from datasets_synthetic.synth import synth
from workbench.errors import UserInputError


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("ds") / "a"
    truth = synth("cornell_cd", out, seed=5)
    return out, truth


def test_layout_and_truth(dataset):
    out, truth = dataset
    assert (out / "photos" / "view0.dng").exists()
    saved = json.loads((out / "truth.json").read_text())
    cam = saved["camera"]
    for key in ("width", "height", "fx", "fy", "cx", "cy", "dist", "world_to_camera"):
        assert key in cam
    assert len(cam["dist"]) == 5 and np.array(cam["world_to_camera"]["view0.dng"]).shape == (4, 4)
    assert saved["exposure_time_s"]["view0.dng"] > 0 and saved["light_power_scale"] > 0 and "response" in saved
    with rawpy.imread(str(out / "photos" / "view0.dng")) as r:
        raw = r.raw_image_visible
        assert raw.shape == (cam["height"], cam["width"])
        assert r.black_level_per_channel[0] == saved["sensor"]["black_level"]
        assert 0 < np.percentile(raw, 99) < saved["sensor"]["white_level"]  # exposed, mostly unclipped


def test_same_seed_same_bytes(dataset, tmp_path):
    out, _ = dataset
    again = tmp_path / "b"
    synth("cornell_cd", again, seed=5)
    assert (again / "photos" / "view0.dng").read_bytes() == (out / "photos" / "view0.dng").read_bytes()
    assert (again / "truth.json").read_text() == (out / "truth.json").read_text()
    other = tmp_path / "c"
    synth("cornell_cd", other, seed=6)
    assert (other / "photos" / "view0.dng").read_bytes() != (out / "photos" / "view0.dng").read_bytes()


def test_refuses_to_mix_datasets(dataset, tmp_path):
    out, _ = dataset
    with pytest.raises(UserInputError, match="holds another dataset"):
        synth("cornell_cd", out, seed=9)
    with pytest.raises(UserInputError, match="--preset"):
        synth("cornell_cd", tmp_path / "x", preset="huge")


def test_scene_without_camera_is_refused(tmp_path):
    from renderer.scene import load_scene

    text = load_scene("cornell_cd").text
    cut = text[: text.index("[camera]")]
    path = tmp_path / "nocam.toml"
    path.write_text(cut)
    with pytest.raises(UserInputError, match="camera"):
        synth(str(path), tmp_path / "y")

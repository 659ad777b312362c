"""A person with one photo and nothing else learns at the first command what each stage needs
(issue 45, item 7): board views for the lens, a bracket or a raw file for the response, and what runs
without them."""

from __future__ import annotations

from pathlib import Path

import pytest

from calibration.dataset import stage_needs
from workbench.cli import main

REAL = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"


@pytest.mark.parametrize("command", [["verify"], ["calibrate"]])
def test_one_photo_given_as_the_dataset_is_refused_with_what_each_stage_needs(tmp_path, capsys, command):
    photo = tmp_path / "mine.dng"
    photo.write_bytes(b"a raw file's bytes")
    assert main([*command, str(photo), "--scene", "cornell_cd", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is a file, not a dataset folder" in err and "photos/mine.dng" in err
    assert "board views in calibration/" in err and "raw photos are linear" in err and "scene fit" in err


def test_the_needs_follow_the_files():
    jpeg = stage_needs({"photos": [Path("a.jpg")], "brackets": [], "boards": []})
    assert "JPEG photos need an exposure bracket" in jpeg[1] and "frees the focal length" in jpeg[0]
    full = stage_needs({"photos": [Path("a.jpg")], "brackets": [Path("b1.jpg"), Path("b2.jpg")],
                        "boards": [Path(f"v{i}.png") for i in range(12)]})
    assert full[0].startswith("intrinsics: 12 board views") and "from the 2 bracket frames" in full[1]

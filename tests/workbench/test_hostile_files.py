"""Hostile structure and scene files end in one line naming the file and field, never a traceback
(issue 46, cause 11): an infinite thickness, a NaN position, an integer past a float's range, arrays
nested too deeply for the TOML parser.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from renderer.scene import load_scene, parse_scene
from workbench.core.errors import UserInputError

CD = (Path(__file__).resolve().parents[2] / "rcwa" / "structures" / "cd.toml").read_text()


@pytest.mark.parametrize(("old", "new", "field"), [
    ("thickness = 0.11", "thickness = inf", "layers[0].thickness"),
    ("thickness = 0.11", "thickness = nan", "layers[0].thickness"),
    ("period = [1.6]", "period = [" + "9" * 400 + "]", "period"),
])
def test_a_structure_with_a_number_that_is_not_finite_is_refused_in_one_line(tmp_path, old, new, field):
    path = tmp_path / "s.toml"
    path.write_text(CD.replace(old, new))
    run = subprocess.run([sys.executable, "-m", "workbench.cli", "rcwa", "solve", str(path), "--wavelength", "550",
                          "--theta", "10", "--orders", "11"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr
    assert run.stderr.startswith("error: ") and field in run.stderr and run.stderr.strip().count("\n") == 0


def test_arrays_nested_too_deeply_are_refused_in_one_line(tmp_path):
    path = tmp_path / "deep.toml"
    path.write_text("x = " + "[" * 5000 + "]" * 5000 + "\n")
    run = subprocess.run([sys.executable, "-m", "workbench.cli", "rcwa", "solve", str(path), "--wavelength", "550",
                          "--orders", "11"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 2 and "nested too deeply" in run.stderr and "Traceback" not in run.stderr


def test_a_scene_with_a_nan_position_names_the_field():
    text = load_scene("cornell_cd").text
    start = text.index("[[cd]]")
    at = text.index("center = [", start)
    end = text.index("]", at)
    with pytest.raises(UserInputError) as caught:
        parse_scene(text[:at] + "center = [nan, 0.1, 0.2" + text[end:], source="bad.toml", base_dir=None)
    assert "bad.toml" in str(caught.value) and "cd[0].center" in str(caught.value)

"""The documentation's examples work: the README's structure file and the complete scene
load, solve and name what they document, so the docs cannot drift from the code."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import rcwa
from renderer.scene import TABLE_OPTIONS, load_scene

ROOT = Path(__file__).resolve().parents[2]
ENERGY_TOL = 1e-9  # R + T + absorption = 1 by construction; absorption >= 0 up to round-off


def test_readme_structure_example_exists_and_solves() -> None:
    readme = (ROOT / "README.md").read_text()
    for path in re.findall(r"rcwa solve (\S+\.toml)", readme):
        structure = rcwa.load_structure(ROOT / path)
        result = rcwa.solve(structure, 600.0, 30.0, 45.0, 41)
        assert result.absorption >= -ENERGY_TOL  # an aluminium grating absorbs, never creates energy
        assert result.R_total + result.T_total + result.absorption == pytest.approx(1.0, abs=ENERGY_TOL)


def test_complete_scene_example_loads_every_kind_of_object() -> None:
    spec = load_scene(ROOT / "docs" / "examples" / "my_scene.toml")
    assert spec.cds and spec.gratings and spec.glass
    assert spec.gratings[0].structure.endswith("my_grating.toml")


def test_scene_format_documents_every_table_option() -> None:
    text = (ROOT / "docs" / "scene_format.md").read_text()
    missing = [key for key in TABLE_OPTIONS if f"`{key}`" not in text]
    assert not missing, f"docs/scene_format.md does not mention the table options {missing}"

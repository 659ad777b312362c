"""Names are never paths (issue 46, cause 2): a structure's ``name`` pasted into the cache path let
``name = "../../../../x/owned"`` build a table anywhere writable, where ``cache list`` and
``cache clear`` never see it. Every hostile name now stays one component inside its folder.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from rcwa.solve_cache import default_cache_path
from renderer.scene import load_scene
from renderer.tables import table_plan
from workbench.core.cache import ENVIRONMENT_VARIABLE, entry_path
from workbench.core.files import SAFE_NAME_LENGTH, path_safe_name

HOSTILE = ["../../../../x/owned", "a/b", "..", ".", ".hidden", "nul\0byte", "x" * 5000, "ünïcödé ✓", "", "a\\b",
           "CON", "name with spaces", "-leading-dash"]


@pytest.mark.parametrize("name", HOSTILE)
def test_a_hostile_name_is_one_safe_component(name):
    safe = path_safe_name(name)
    assert safe and "/" not in safe and "\\" not in safe and "\0" not in safe and not safe.startswith(".")
    assert len(safe) <= max(SAFE_NAME_LENGTH, len(name)) and safe.isascii()
    assert Path(safe).name == safe and safe not in (".", "..")


def test_safe_names_are_kept_and_different_hostile_names_stay_apart():
    assert path_safe_name("cd") == "cd" and path_safe_name("gold2d-v1.2") == "gold2d-v1.2"
    assert path_safe_name("a/b") != path_safe_name("a_b") and path_safe_name("x" * 70) != path_safe_name("x" * 71)


def test_the_cache_refuses_a_name_that_is_a_path():
    with pytest.raises(ValueError, match="safe path component"):
        entry_path("tables", "../outside.zarr")


@pytest.mark.parametrize("name", ["../../../../x/owned", "a/b/c", "..", "x" * 300])
def test_a_scenes_table_with_a_hostile_structure_name_stays_in_the_cache(tmp_path, monkeypatch, name):
    monkeypatch.setenv(ENVIRONMENT_VARIABLE, str(tmp_path / "cache"))
    cd = load_scene("cornell_cd").cds[0]
    structure = Path(cd.structure) if Path(str(cd.structure)).is_file() else None
    text = (structure.read_text() if structure else (Path(__file__).parents[2] / "rcwa/structures/cd.toml").read_text())
    hostile = tmp_path / "hostile.toml"
    hostile.write_text(text.replace('name = "cd"', f"name = {name!r}".replace("'", '"')))
    plan = table_plan(dataclasses.replace(cd, structure=str(hostile)))
    tables = (tmp_path / "cache" / "tables").resolve()
    assert plan.path.resolve().parent == tables, plan.path
    assert default_cache_path(name).resolve().parent == (tmp_path / "cache" / "convergence").resolve()

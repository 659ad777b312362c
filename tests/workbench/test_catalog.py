"""`workbench list KIND` and `workbench rcwa info TABLE` (workbench/catalog.py, issue 13):
what is built in, each with a line about it, and what a table holds and whether it is
intact."""

from __future__ import annotations

import json

import pytest

from workbench.catalog import KINDS
from workbench.cli import main


def _accepts(kind: str, name: str) -> None:
    """The name `workbench list` shows is one the commands and files accept."""
    if kind == "structures":
        import rcwa

        rcwa.load_structure(name)
    elif kind == "scenes":
        from renderer.scene import load_scene

        load_scene(name)
    elif kind == "materials":
        from rcwa.materials import material_from_spec

        material_from_spec(name)
    else:
        import colour

        assert name in colour.MSDS_CAMERA_SENSITIVITIES


@pytest.mark.parametrize("kind", KINDS)
def test_list_shows_every_builtin_with_a_line_about_it(kind: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["list", kind]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines, f"no {kind} listed"
    for line in lines:
        name, _, description = line.partition("  ")
        assert description.strip(), f"{kind}: {name!r} has no description"
        _accepts(kind, name.strip())


def test_list_names_the_builtins_the_readme_names(capsys: pytest.CaptureFixture[str]) -> None:
    listed = {}
    for kind in ("structures", "scenes"):
        main(["list", kind])
        listed[kind] = {line.split()[0] for line in capsys.readouterr().out.splitlines()}
    assert {"cd", "gold2d"} <= listed["structures"]
    assert {"cornell_cd", "cornell_cd_view2", "grating2d_gold"} <= listed["scenes"]


def test_rcwa_info_shows_grid_settings_size_symmetry_and_integrity(tmp_path, capsys) -> None:
    table = tmp_path / "t.zarr"
    assert main(["rcwa", "table", "cd", "--out", str(table), "--preset", "draft", "--wavelengths", "500,600",
                 "--theta-step", "45", "--phi-step", "45", "--orders", "11", "--keep-orders", "5", "--quiet"]) == 0
    capsys.readouterr()
    assert main(["rcwa", "info", str(table), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["wavelengths_nm"] == {"count": 2, "first": 500.0, "last": 600.0}
    assert info["theta_deg"]["step"] == 45.0 and info["orders_retained"] == [11] and info["orders_kept"] == [5]
    assert info["symmetry"]["mirror_x"] and info["bytes_on_disk"] > 0 and info["integrity"].startswith("intact")
    assert main(["rcwa", "info", str(table)]) == 0
    text = capsys.readouterr().out
    for word in ("wavelengths", "theta", "phi", "orders", "symmetry", "size", "integrity     intact"):
        assert word in text, text

    chunk = sorted(p for p in (table / "R" / "c").rglob("*") if p.is_file())[1]
    chunk.write_bytes(b"")
    assert main(["rcwa", "info", str(table)]) == 0  # a damaged table is described, not refused
    text = capsys.readouterr().out
    assert "NOT intact" in text and "chunk 1" in text and "workbench rcwa table" in text, text


def test_rcwa_info_says_a_table_is_planned(tmp_path, capsys) -> None:
    """A planned table (rcwa.table.NodePlan: the nodes a camera reads, the rest with fewer orders) says so, with how
    many nodes carry the table's orders (3 of the small grid here)."""
    import numpy as np

    import rcwa
    from rcwa.table import NodePlan, build_table, planned, settings_for

    structure = rcwa.load_structure("cd")
    settings = settings_for(structure, "draft", wavelengths="500,600", theta_step=40.0, phi_step=45.0,
                            orders=11, keep=5)
    shape = (len(settings.wavelengths_nm), len(settings.theta_deg), len(settings.phi_deg))
    mask = np.zeros(shape, bool)
    mask.ravel()[[0, 5, 7]] = True
    plan = NodePlan(mask, (5,))
    table = tmp_path / "planned.zarr"
    build_table(structure, planned(settings, plan), table, progress=False, nodes=plan)
    assert main(["rcwa", "info", str(table), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["planned"]["nodes_solved"] == 3 and info["planned"]["nodes"] == mask.size
    assert info["planned"]["fill_orders"] == [5]
    assert main(["rcwa", "info", str(table)]) == 0
    assert f"3 of {mask.size} nodes solved" in capsys.readouterr().out


def test_a_built_in_scene_exported_edited_and_rendered(tmp_path, capsys):
    """Issue 45, item 5: a user copies cornell_cd out to change its resolution; the copy renders as edited."""
    import json

    from workbench.cli import main

    scene = tmp_path / "mine.toml"
    assert main(["list", "scenes", "--export", "cornell_cd", "--out", str(scene)]) == 0
    text = scene.read_text()
    start = text.index("resolution = [", text.index("[camera]"))
    scene.write_text(text[:start] + "resolution = [64, 48]" + text[text.index("]", start) + 1:])
    assert main(["render", str(scene), "--out", str(tmp_path / "r.exr"), "--spp", "2", "--quiet"]) == 0
    assert json.loads((tmp_path / "r.json").read_text())["resolution"] == [64, 48]
    assert main(["list", "scenes", "--export", "cornell_cd", "--out", str(scene)]) == 2  # no silent overwrite
    assert main(["list", "structures", "--export", "cd", "--out", str(tmp_path / "cd.toml")]) == 0
    assert main(["render", str(tmp_path / "cd.toml"), "--out", str(tmp_path / "x.exr")]) == 2  # a structure is no scene
    assert main(["list", "materials", "--export", "gold"]) == 2

"""A damaged table in the cache, met by `workbench render`, is computed again or passed
over, never a dead end (issue 13: before, render refused with "field 'cd[0].table.path'"
for a scene that names no path, and advised a command that could not rebuild a planned
table, so every later render of the scene failed the same way).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from rcwa.table import NodePlan, build_table, open_table
from renderer.scene import load_scene
from renderer.spectra import camera_sensitivities
from renderer.tables import element_table, table_plan
from workbench.cli import main
from workbench.core.cache import ENVIRONMENT_VARIABLE

# The repaired chunks are solved again by the same deterministic solver with the same
# settings, and the render uses the same seeds: the images must be equal to float32
# round-off (measured: identical bits).
IMAGE_RTOL = 1e-6
SMALL_TABLE = {"preset": "draft", "wavelengths": "400:700:7", "theta_step": 10.0, "phi_step": 15.0, "orders": 21,
               "keep": 7}


def _chunks(table: Path) -> list[Path]:
    return sorted(p for p in (table / "R" / "c").rglob("*") if p.is_file())


def _exr(path: Path) -> np.ndarray:
    import mitsuba as mi

    return np.array(mi.Bitmap(str(path)))


def test_render_computes_a_damaged_cached_table_again_and_says_so(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.setenv(ENVIRONMENT_VARIABLE, str(tmp_path / "cache"))
    argv = ["render", "cornell_cd", "--spp", "4", "--resolution", "48x36", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "a.exr")]) == 0
    assert "wavelength/s" not in capsys.readouterr().err  # --quiet: no bar, not even the table build's
    (table,) = (tmp_path / "cache" / "tables").glob("*.zarr")
    chunks = _chunks(table)
    chunks[1].write_bytes(b"")  # truncated
    chunks[3].unlink()  # deleted
    with pytest.raises(Exception, match="chunk"):
        open_table(table)
    capsys.readouterr()
    assert main([*argv, "--out", str(tmp_path / "b.exr")]) == 0
    err = capsys.readouterr().err
    assert "computed again" in err and "Traceback" not in err, err
    open_table(table)  # every checksum matches again
    np.testing.assert_allclose(_exr(tmp_path / "b.exr"), _exr(tmp_path / "a.exr"), rtol=IMAGE_RTOL, atol=0)


def test_a_damaged_table_of_another_plan_is_passed_over(tmp_path, monkeypatch, capsys) -> None:
    """Another camera's planned table that covers this plan serves it when intact; damaged,
    this plan's own table is built instead, and the message says why."""
    monkeypatch.setenv(ENVIRONMENT_VARIABLE, str(tmp_path / "cache"))
    spec = load_scene("cornell_cd")
    cd = dataclasses.replace(spec.cds[0], table=SMALL_TABLE)
    settings = table_plan(cd).settings
    shape = (len(settings.wavelengths_nm), len(settings.theta_deg), len(settings.phi_deg))
    mask = np.indices(shape).sum(axis=0) % 2 == 0
    other = table_plan(cd, "cd[0]", None, NodePlan(mask, (7,)))
    build_table(other.structure, other.settings, other.path, progress=False, nodes=other.nodes)
    subset = NodePlan(mask & (np.arange(shape[0]) < 3)[:, None, None], (7,))
    assert table_plan(cd, "cd[0]", None, subset).path == other.path  # intact, it serves the subset

    _chunks(other.path)[0].write_bytes(b"")
    sens = camera_sensitivities(spec.camera.sensitivities)
    path = element_table(cd, sens, "cd[0]", None, subset)
    err = capsys.readouterr().err
    assert path != other.path and f"{other.path}: not used" in err and "chunk 0" in err, err
    assert open_table(path).meta["planned"]["fill_orders"] == [7]

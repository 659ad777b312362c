"""Small gold2d tables for the diagonal-mirror tests (tests/rcwa/test_symmetry_diagonal.py,
tests/renderer/test_efficiency_diagonal.py): the same grid built folded by the diagonal
mirror (azimuths 0-45 deg), as tables written before the diagonal existed did (0-90 deg,
no ``mirror_diagonal`` in the metadata), and unfolded (0-360 deg, use_symmetry=False).

2 wavelengths x 4 polar angles, 3 x 3 retained and kept orders: a few hundred small solves.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import rcwa
from rcwa import symmetry
from rcwa.structure import Structure
from rcwa.table import Table, TableSettings, build_table, open_table, settings_for


@dataclass
class DiagonalTables:
    folded: Table     # x, y and diagonal mirrors: phi 0-45
    old: Table        # x and y mirrors, metadata of the format before the diagonal: phi 0-90
    unfolded: Table   # no symmetry: phi 0-345


def build_tables(folder: Path, monkeypatch_context) -> DiagonalTables:
    """``monkeypatch_context``: pytest.MonkeyPatch.context (the old-format table is built
    with the diagonal switched off, as the code before it did)."""
    import rcwa.table.settings as table_module

    s = rcwa.load_structure("gold2d")
    folded = _settings(s)
    build_table(s, folded, folder / "folded.zarr", progress=False, threads=1)
    unfolded = _settings(s, use_symmetry=False)
    build_table(s, unfolded, folder / "unfolded.zarr", progress=False, threads=1)
    with monkeypatch_context() as mp:
        mp.setattr(table_module, "table_symmetry", lambda *a: symmetry.MirrorSymmetry(True, True))
        old = _settings(s)
        build_table(s, old, folder / "old.zarr", progress=False, threads=1)
    _strip_diagonal_keys(folder / "old.zarr")
    return DiagonalTables(open_table(folder / "folded.zarr"), open_table(folder / "old.zarr"),
                          open_table(folder / "unfolded.zarr"))


def _settings(structure: Structure, use_symmetry: bool = True) -> TableSettings:
    return settings_for(structure, "draft", wavelengths="550,650", theta_step=30.0, phi_step=15.0, orders=3, keep=3,
                        use_symmetry=use_symmetry)


def _strip_diagonal_keys(path: Path) -> None:
    """The table's metadata as written before the diagonal mirror existed (the chunks'
    checksums do not cover the metadata, so the table still opens)."""
    meta_file = path / "zarr.json"
    meta = json.loads(meta_file.read_text())
    for key in ("mirror_diagonal", "description", "note"):
        del meta["attributes"]["symmetry"][key]
    meta_file.write_text(json.dumps(meta))

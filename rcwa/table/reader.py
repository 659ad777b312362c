"""Reading a finished table: every chunk checked against its checksum, clear errors
(naming the chunk and the command that rebuilds it) otherwise.

Azimuths: mirror symmetries of the cell (rcwa.symmetry) shrink the azimuth range that is
computed (0-90 deg with the x and y mirrors; 0-45 deg when a square cell with a square
truncation also has the diagonal mirror x <-> y); ``Table.fold_azimuth`` maps any azimuth
into it (with the order flips and the swap, rcwa.symmetry.fold_azimuths). The stored
azimuths reach the range's end: where the step does not divide the range, the last node
lies one step past it, so bilinear interpolation up to the end never clamps. Metadata of
tables written before the diagonal mirror existed lack ``mirror_diagonal``: read as False.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcwa import symmetry
from rcwa.table.store import chunk_hash, read_meta, read_progress
from workbench.core.errors import UserInputError


def read_table_metadata(path: str | Path) -> dict:
    """A table's metadata (grid, settings, symmetry, orders) without reading its data.

    Raises UserInputError naming the path when it is not a table of ours.
    """
    path = Path(path)
    meta = read_meta(path) if path.is_dir() else None
    if meta is None or meta.get("format") != "workbench-efficiency-table":
        raise UserInputError("not an efficiency table (no readable zarr.json with our format)", file=path,
                             expected="a folder written by `workbench rcwa table`")
    return meta


@dataclass
class Table:
    """A finished, verified table. ``arrays[name]``: (wavelength, theta, phi, order, pol)."""

    path: Path
    meta: dict
    arrays: dict[str, np.ndarray]

    @property
    def wavelengths_nm(self) -> np.ndarray:
        return np.asarray(self.meta["settings"]["wavelengths_nm"])

    @property
    def theta_deg(self) -> np.ndarray:
        return np.asarray(self.meta["settings"]["theta_deg"])

    @property
    def phi_deg(self) -> np.ndarray:
        return np.asarray(self.meta["settings"]["phi_deg"])

    @property
    def orders(self) -> list[tuple[int, int]]:
        return list(zip(self.meta["orders_m"], self.meta["orders_n"], strict=True))

    @property
    def mirrors(self) -> tuple[bool, bool, bool]:
        """(x, y, diagonal) mirrors the table's azimuths are folded by; tables written
        before the diagonal existed have no ``mirror_diagonal``: False."""
        sym = self.meta["symmetry"]
        return bool(sym["mirror_x"]), bool(sym["mirror_y"]), bool(sym.get("mirror_diagonal", False))

    def fold_azimuth(self, phi_deg: float) -> tuple[float, bool, bool, bool]:
        """Map an azimuth into the stored range: (phi, flip m, flip n, swap m and n); order
        (m, n) is stored as rcwa.symmetry.stored_order(m, n, flip m, flip n, swap)
        (rcwa.symmetry.fold_azimuths)."""
        phi, flip_m, flip_n, swap = symmetry.fold_azimuths(float(phi_deg), *self.mirrors)
        return float(phi), bool(flip_m), bool(flip_n), bool(swap)

    def stored_index(self, m: int, n: int, flip_m: bool, flip_n: bool, swap: bool) -> int:
        """Index (into the order axis) of the stored order that holds order (m, n) at a
        folded azimuth (fold_azimuth's flips and swap)."""
        sm, sn = symmetry.stored_order(m, n, flip_m, flip_n, swap)
        return self.orders.index((int(sm), int(sn)))


def open_table(path: str | Path) -> Table:
    """Open a finished table, verifying every chunk's checksum; clear errors otherwise."""
    import zarr  # deferred: start-up time

    path = Path(path)
    meta = read_meta(path)
    if meta is None or meta.get("format") != "workbench-efficiency-table":
        raise UserInputError("not an efficiency table (no readable zarr.json with our format)", file=path)
    repair = _repair_advice(path, meta)
    if not meta.get("complete"):
        raise UserInputError(f"the table is unfinished; {repair} to resume it", file=path)
    done = read_progress(path)
    group = zarr.open_group(str(path), mode="r")
    arrays: dict[str, np.ndarray] = {}
    count = len(meta["settings"]["wavelengths_nm"])
    for name in meta["arrays"]:
        try:
            arrays[name] = np.stack([_read_chunk(group, name, i) for i in range(count)])
        except _ChunkUnreadable as exc:
            raise UserInputError(f"array {name}, {_chunk_words(meta, exc.index)} cannot be read ({exc.reason}); "
                                 f"{repair}: damaged chunks are computed again", file=path) from None
    for i in range(count):
        record = done.get(str(i))
        if record is None or chunk_hash({name: arrays[name][i] for name in arrays}) != record["sha256"]:
            raise UserInputError(f"{_chunk_words(meta, i)} is damaged or missing (its checksum does not match); "
                                 f"{repair}: damaged chunks are computed again", file=path)
    return Table(path, meta, arrays)


class _ChunkUnreadable(Exception):
    def __init__(self, index: int, reason: str) -> None:
        super().__init__(reason)
        self.index, self.reason = index, reason


def _read_chunk(group, name: str, index: int) -> np.ndarray:
    try:
        return group[name][index]
    except Exception as exc:  # a truncated chunk file, a deleted array
        raise _ChunkUnreadable(index, f"{type(exc).__name__}: {exc}") from None


def _chunk_words(meta: dict, index: int) -> str:
    return f"chunk {index} (wavelength {meta['settings']['wavelengths_nm'][index]:g} nm)"


def _repair_advice(path: Path, meta: dict) -> str:
    """The command that rebuilds a table: the one that made it (the render of a scene, for a cached one)."""
    source = str(meta.get("structure_source", "STRUCTURE"))
    structure = meta.get("structure_name", source) if source.startswith("<built-in") else source
    return (f"run `workbench rcwa table {structure} --out {path}` with the options that built it (or the render that "
            "uses it) again")

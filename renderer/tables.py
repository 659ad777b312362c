"""The scene's efficiency tables: which table serves each CD and grating, built when missing.

A CD's or grating's efficiency table is the one its ``table = { path = ... }`` names
(checked: finished, intact, built for the element's structure), or else built through the
table cache (workbench.core.cache, ``tables/``, named by the request's content hash) when
missing; either is checked to cover where the camera sees (renderer.camera_coverage). A table
planned for one camera (renderer.trace.planner) holds the nodes its rays read solved in full; a
finished planned table whose exact nodes include another plan's serves that plan too.
"""

from __future__ import annotations

import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import rcwa
from rcwa.table import (
    build_table,
    check_materials,
    open_table,
    planned,
    read_table_metadata,
    request_key,
    settings_for,
)
from renderer.camera_coverage import require_table_covers_camera
from renderer.scene import SceneSpec
from renderer.spectra import Curves, on_common_grid
from workbench.core.cache import entry_path
from workbench.core.errors import UserInputError
from workbench.core.files import path_safe_name


@dataclass(frozen=True)
class TablePlan:
    """An element's efficiency table: where it is, the request it holds (rcwa.table's key),
    and the settings to build it with (None for a table the scene names by ``path``).
    """

    path: Path
    key: str
    structure: Any
    settings: Any
    nodes: Any = None  # rcwa.table.NodePlan of a planned table (None: the whole table)
    fallback: TablePlan | None = None  # for another plan's table serving this one: this plan's own, if that one is damaged


# rcwa.table.settings_for names the command line's options; a scene's table = {...} has these keys
SCENE_TABLE_KEYS = {"--preset": "preset", "--wavelengths": "wavelengths", "--orders": "orders", "--keep-orders": "keep",
                    "--theta-step": "theta_step", "--phi-step": "phi_step", "--theta-range": "theta_range",
                    "--phi-range": "phi_range", "--pol": "pol", "--factorization": "factorization"}


def _tell_user(message: str) -> None:
    """What this module says while it serves tables: on stderr, whatever the progress bars
    (a damaged table passed over or repaired is news even in a quiet run)."""
    print(message, file=sys.stderr)


def scene_settings_for(structure, preset: str, options: dict, where: str, scene_file: str | None):
    """rcwa.table.settings_for of a scene element's table options; a refused option names the
    scene file and field (``cd[0].table.keep``), not the command line's (``--keep-orders``)."""
    try:
        settings = settings_for(structure, preset, **options)
    except UserInputError as exc:
        raise _in_scene(exc, where, scene_file) from None
    try:
        check_materials(structure, settings)
    except UserInputError as exc:  # names the structure's field; the scene asked for the wavelengths
        raise UserInputError(f"{exc.reason.split(';')[0]} (in {exc.file}, field '{exc.field}')", file=scene_file,
                             field=f"{where}.table.wavelengths", expected="wavelengths inside every material's data",
                             got=options.get("wavelengths", f"the {preset} preset's")) from None
    return settings


def _in_scene(exc: UserInputError, where: str, scene_file: str | None) -> UserInputError:
    """``exc`` about a command-line option (SCENE_TABLE_KEYS) as the scene field it came from."""
    key = SCENE_TABLE_KEYS.get(exc.field or "")
    if key is None:
        return exc
    expected = (exc.expected or "").replace(f"--{key.replace('_', '-')}", key) or None
    return UserInputError(exc.reason, file=scene_file, field=f"{where}.table.{key}", expected=expected, got=exc.got)


def table_settings(element, structure, where: str = "element", scene_file: str | None = None):
    """The table settings of an element's ``table = {...}`` (not ``path``): the scene's
    options, with light from below for a see-through element (scene_settings_for)."""
    options = {k: v for k, v in dict(element.table).items() if k != "path"}
    preset = options.pop("preset", "draft")
    eps = np.asarray(structure.substrate.epsilon(np.array([550.0])))
    if np.all((eps.imag == 0) & (eps.real > 0)):
        options.setdefault("both_sides", True)  # see-through: light from below too
    return scene_settings_for(structure, preset, options, where, scene_file)


def table_plan(element, where: str = "element", scene_file: str | None = None, nodes=None) -> TablePlan:
    """Where a CD's or grating's table is and what it holds, without building it.

    ``nodes`` (rcwa.table.NodePlan, from renderer.trace.planner): a planned table, unless the
    whole table is in the cache already (it serves every plan)."""
    structure = rcwa.load_structure(element.structure)
    options = dict(element.table)
    if "path" in options:  # alone (renderer.scene checks), relative paths already resolved against the scene file
        return _named_table_plan(Path(options["path"]), structure, where, scene_file)
    settings = table_settings(element, structure, where, scene_file)
    key = request_key(structure, settings)
    whole = TablePlan(entry_path("tables", f"{path_safe_name(structure.name)}-{key[:16]}.zarr"), key, structure, settings)
    if nodes is None or _finished_table(whole.path, key) is not None:
        return whole
    settings = planned(settings, nodes)
    planned_key = request_key(structure, settings)
    own = TablePlan(whole.path.with_name(f"{whole.path.stem}-planned-{planned_key[:12]}.zarr"), planned_key, structure,
                    settings, nodes)
    if own.path.exists():  # this plan's own table: build_table serves it, resumes it or computes damaged chunks again
        return own
    return _planned_superset(whole.path, nodes, own) or own


def _named_table_plan(path: Path, structure, where: str, scene_file: str | None) -> TablePlan:
    """The plan of the table a scene names by ``path`` (its key read from its metadata)."""
    try:
        meta = read_table_metadata(path)
    except UserInputError as exc:
        raise UserInputError(f"{path}: {exc.reason}", file=scene_file, field=f"{where}.table.path",
                             expected=exc.expected) from None
    return TablePlan(path, meta["key"], structure, None)


def _finished_table(path: Path, key: str | None = None) -> dict | None:
    """The metadata of a finished table at ``path`` (of request ``key`` when given), or None."""
    try:
        meta = read_table_metadata(path)
    except UserInputError:
        return None
    return meta if meta.get("complete") and key in (None, meta.get("key")) else None


def _planned_superset(whole: Path, nodes, own: TablePlan) -> TablePlan | None:
    """A finished planned table of the same request whose exactly solved nodes include
    ``nodes``' with the same fill: it serves this plan (another camera's plan, a run's plan
    for the scene's camera with a margin). ``own`` (this plan's table) is its fallback."""
    import zarr  # deferred: start-up time

    for path in sorted(whole.parent.glob(f"{whole.stem}-planned-*.zarr")):
        meta = _finished_table(path)
        if meta is None or meta.get("planned", {}).get("fill_orders") != list(nodes.fill_orders):
            continue
        try:
            mask = np.asarray(zarr.open_array(str(path / "planned_nodes"), mode="r")[...], bool)
        except Exception:  # unreadable: not a candidate
            continue
        if mask.shape == nodes.mask.shape and not np.any(nodes.mask & ~mask):
            return TablePlan(path, meta["key"], own.structure, None, fallback=own)  # built: checked like a named table
    return None


def table_keys(spec: SceneSpec) -> list[str]:
    """The request keys of a scene's tables (their content, wherever the cache is), in order."""
    elements = ([(f"cd[{i}]", cd) for i, cd in enumerate(spec.cds)]
                + [(f"grating[{i}]", g) for i, g in enumerate(spec.gratings)])
    return [table_plan(element, where, spec.source).key for where, element in elements]


def element_table(element, camera_sens: Curves, where: str = "element", scene_file: str | None = None, nodes=None,
                  progress: bool = True) -> Path:
    """The efficiency table of a CD or grating: the one its scene names (checked), or built
    through the table cache (planned with ``nodes``: see table_plan). ``where`` (``cd[0]``)
    and ``scene_file`` locate errors; ``progress``: a bar while a table is built.
    """
    plan = table_plan(element, where, scene_file, nodes)
    if plan.settings is None:
        try:
            wavelengths = _check_named_table(plan, where, scene_file)
        except UserInputError as exc:
            if plan.fallback is None:  # a table the scene names: the user's to repair
                raise
            _tell_user(f"{plan.path}: not used ({exc.reason}); building this camera's own table")
            plan = plan.fallback
    if plan.settings is not None:
        wavelengths = _built_table_wavelengths(plan, where, scene_file, progress)
    wl, curves = on_common_grid(camera_sens)
    require_table_covers_camera(str(plan.path), wavelengths, wl, curves)
    return plan.path


def _built_table_wavelengths(plan: TablePlan, where: str, scene_file: str | None, progress: bool) -> np.ndarray:
    """Build (or serve, resume, repair) the cache's table of ``plan``; its wavelengths."""
    try:
        report = build_table(plan.structure, plan.settings, plan.path, progress=progress, force=True,  # the cache's
                             nodes=plan.nodes)
        for note in report.notes:  # damaged chunks computed again: say so, as `rcwa table` does
            _tell_user(f"{plan.path}: {note}")
    except UserInputError as exc:  # e.g. wavelengths outside a material's data: say which scene field asked
        raise UserInputError(f"its table cannot be built: {exc}", file=scene_file, field=f"{where}.table") from None
    return np.asarray(plan.settings.wavelengths_nm)


def _check_named_table(plan: TablePlan, where: str, scene_file: str | None) -> np.ndarray:
    """A table a scene names must be finished, intact, built for the element's structure,
    and hold light from below when the element is see-through; its wavelengths.
    """
    field = f"{where}.table.path"
    try:
        table = open_table(plan.path)  # finished, every chunk's checksum
    except UserInputError as exc:
        raise UserInputError(f"{plan.path}: {exc.reason}", file=scene_file, field=field) from None
    if tomllib.loads(table.meta["structure_text"]) != tomllib.loads(plan.structure.text):
        raise UserInputError(f"{plan.path} was built for another structure ({table.meta['structure_source']}), not the "
                             f"element's ({plan.structure.source})", file=scene_file, field=field,
                             expected=f"a table built with `workbench rcwa table {plan.structure.source} ...`")
    arrays = set(table.meta["arrays"])
    if "T" in arrays and not {"R_below", "T_below"} <= arrays:
        raise UserInputError(f"{plan.path}: the element is see-through (its substrate transmits) and needs light from "
                             "both sides", file=scene_file, field=field, expected="a table built with --both-sides")
    return table.wavelengths_nm

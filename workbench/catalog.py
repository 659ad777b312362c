"""What the workbench offers, in words: the built-ins (``workbench list``) and what a
table holds (``workbench rcwa info``).

Part of the face (the command line's package): it reads the libraries' own descriptions
(a structure's or scene's ``description`` field, a material file's first comment line,
colour-science's camera names) and formats them; nothing here is computed.
"""

from __future__ import annotations

import time
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from workbench.core.errors import UserInputError

DEFAULT_CAMERA = "Nikon 5100 (NPL)"  # renderer.scene's default sensitivities
KINDS = ("structures", "scenes", "materials", "cameras")


@dataclass(frozen=True)
class Entry:
    """One built-in: its name (what a command or file accepts) and one line about it."""

    name: str
    description: str


def builtins(kind: str) -> list[Entry]:
    """The built-ins of one kind (one of :data:`KINDS`)."""
    return {"structures": _structures, "scenes": _scenes, "materials": _materials, "cameras": _cameras}[kind]()


def _toml_description(package: str, name: str) -> str:
    text = resources.files(package).joinpath(f"{name}.toml").read_text(encoding="utf-8")
    return str(tomllib.loads(text).get("description", "")).strip() or _first_comment(text)


def _first_comment(text: str) -> str:
    for line in text.splitlines():
        if line.startswith("#"):
            return line.lstrip("# ").strip()
    return ""


def _structures() -> list[Entry]:
    from rcwa.structure import BUILTIN_STRUCTURES  # deferred: rcwa.structure pulls in scipy (start-up time)

    return [Entry(n, _toml_description("rcwa.structures", n)) for n in BUILTIN_STRUCTURES]


def _scenes() -> list[Entry]:
    from renderer.scene import BUILTIN_SCENES  # deferred: the renderer pulls in scipy (start-up time)

    return [Entry(n, _toml_description("renderer.scenes", n)) for n in BUILTIN_SCENES]


def _materials() -> list[Entry]:
    from rcwa.materials import BUILTIN_MATERIALS  # deferred: rcwa.materials pulls in scipy (start-up time)

    entries = []
    for name in BUILTIN_MATERIALS:
        text = resources.files("rcwa.materials_data").joinpath(f"{name}.toml").read_text(encoding="utf-8")
        entries.append(Entry(name, _first_comment(text)))
    return entries


def _cameras() -> list[Entry]:
    import colour  # deferred: start-up time

    names = sorted(colour.MSDS_CAMERA_SENSITIVITIES)
    return [Entry(n, "measured RGB spectral sensitivities (colour-science)" + (", the default" if n == DEFAULT_CAMERA else ""))
            for n in names]


def format_builtins(kind: str) -> str:
    entries = builtins(kind)
    width = max(len(e.name) for e in entries)
    return "\n".join(f"{e.name:<{width}}  {e.description}" for e in entries)


def table_info(path: str | Path) -> dict:
    """What a table built by ``workbench rcwa table`` holds, and whether it is intact.

    Raises UserInputError (from rcwa.table) for something that is not a table; a damaged
    or unfinished table is reported (``integrity``) rather than refused, since finding
    out is why one asks.
    """
    from rcwa.table import open_table, read_table_metadata  # deferred: rcwa.table pulls in scipy (start-up time)

    path = Path(path)
    meta = read_table_metadata(path)
    settings = meta["settings"]
    start = time.perf_counter()
    try:
        open_table(path)
        integrity = "intact: every chunk's checksum matches"
    except UserInputError as exc:
        integrity = f"NOT intact: {exc.reason}"
    wl = settings["wavelengths_nm"]
    return {
        "path": str(path), "structure": meta["structure_name"], "structure_source": meta["structure_source"],
        "structure_sha256": meta["structure_sha256"], "request_key": meta["key"],
        "arrays": meta["arrays"], "polarizations": meta["pol_names"],
        "wavelengths_nm": {"count": len(wl), "first": wl[0], "last": wl[-1]},
        "theta_deg": _axis(settings["theta_deg"]), "phi_deg": _axis(settings["phi_deg"]),
        "orders_retained": settings["orders"], "orders_kept": settings["keep"], "factorization": meta["factorization"],
        "symmetry": meta["symmetry"], "solver_version": meta["solver_version"], "complete": bool(meta.get("complete")),
        "bytes_on_disk": sum(f.stat().st_size for f in path.rglob("*") if f.is_file()),
        "integrity": integrity, "check_seconds": time.perf_counter() - start,
        "planned": _planned(path, settings),
    }


def _planned(path: Path, settings: dict) -> dict | None:
    """A planned table (rcwa.table.NodePlan): how many nodes hold the table's orders, the others' orders."""
    if not settings.get("planned_nodes_sha256"):
        return None
    from rcwa.table import PLANNED_NODES  # deferred: as in table_info

    solved: int | None = None
    total: int | None = None
    try:
        import zarr  # deferred: start-up time

        mask = np.asarray(zarr.open_array(str(path / PLANNED_NODES), mode="r")[:], bool)
        solved, total = int(mask.sum()), int(mask.size)
    except (KeyError, OSError, ValueError):
        pass
    return {"nodes_solved": solved, "nodes": total, "fill_orders": settings.get("fill_orders"),
            "digest": settings["planned_nodes_sha256"]}


def _axis(values: list[float]) -> dict:
    step = values[1] - values[0] if len(values) > 1 else 0.0
    return {"count": len(values), "first": values[0], "last": values[-1], "step": step}


def format_table_info(info: dict) -> str:
    t, p, w = info["theta_deg"], info["phi_deg"], info["wavelengths_nm"]
    sym = info["symmetry"]
    # tables written before the diagonal mirror existed have no mirror_diagonal: not folded by it
    mirrors = [a for a, on in (("x", sym["mirror_x"]), ("y", sym["mirror_y"]),
                               ("diagonal x <-> y", sym.get("mirror_diagonal", False))) if on]
    note = sym.get("note", "")  # why a mirror of the cell is not used (a truncation that breaks it)
    lines = [
        f"{info['path']}: efficiency table of {info['structure']} ({info['structure_source']})",
        f"  arrays        {', '.join(info['arrays'])} (wavelength x theta x phi x kept order x polarization: "
        f"{', '.join(info['polarizations'])})",
        f"  wavelengths   {w['count']} from {w['first']:g} to {w['last']:g} nm",
        f"  theta         {t['count']} from {t['first']:g} to {t['last']:g} deg (step {t['step']:g})",
        f"  phi           {p['count']} from {p['first']:g} to {p['last']:g} deg (step {p['step']:g})",
        f"  orders        {'x'.join(map(str, info['orders_retained']))} retained, "
        f"{'x'.join(map(str, info['orders_kept']))} kept; factorization {info['factorization']}",
        f"  symmetry      mirror {' and '.join(mirrors) or 'none'}; azimuths stored "
        f"{sym['phi_range_deg'][0]:g}-{sym['phi_range_deg'][1]:g} deg{f' ({note})' if note else ''}",
        f"  size          {info['bytes_on_disk'] / 1e6:.2f} MB on disk; solver {info['solver_version']}",
        f"  integrity     {info['integrity']} ({info['check_seconds']:.2f} s to check)",
    ]
    plan = info.get("planned")
    if plan:
        share = (f"{plan['nodes_solved']} of {plan['nodes']} nodes" if plan["nodes"] else "its nodes (mask unreadable)")
        fill = "x".join(map(str, plan["fill_orders"] or []))
        lines.insert(-2, f"  planned       {share} solved with the retained orders (the nodes a render's camera reads); "
                         f"the others with {fill} (renderer.trace.planner)")
    return "\n".join(lines)

"""The layering check of ``make check``: import cycles, private imports, long modules and functions.

Run as ``python -m tests.check_layering [--root DIR]``; it reads every module of the shipped
packages with ``ast`` (imports inside functions included, relative imports resolved) and
exits 1 with a list of what it found:

- an import cycle between modules: each strongly connected component of the module graph
  (Tarjan 1972) with more than one module, or a module importing itself, with the edges
  that close it. ``from pkg import name`` counts as importing ``pkg.name`` where that is a
  submodule, else as importing ``pkg`` (its ``__init__``); the parent packages a dotted
  import runs implicitly are not edges (every submodule would otherwise close a cycle with
  a package ``__init__`` that re-exports it);
- a module importing a private name (``_x``) of another top-level package, as
  ``from a.b import _c``, ``from a._b import c`` or ``import a._b``; private imports within
  one top-level package are allowed;
- a module over ``MAX_MODULE_LINES`` lines (``renderer/bwdf.py`` exempt: the BWDF plugin
  stays one file, as Mitsuba keeps a plugin);
- a function over ``MAX_FUNCTION_LINES`` lines (argument-parser builders exempt).

Every function takes the repository root as a parameter, so tests run it on probe trees.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHIPPED_PACKAGES = ("rcwa", "renderer", "calibration", "datasets_synthetic", "reports", "workbench")
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 60
LONG_MODULES_ALLOWED = frozenset({"renderer/bwdf.py"})
PARSER_BUILDER_PREFIXES = ("add_parser", "_build_parser", "add_arguments")


@dataclass(frozen=True)
class ImportEdge:
    """One import statement's target: ``importer`` imports ``target`` at ``path:line``.

    ``name`` is the imported name for ``from target import name`` (None for ``import target``).
    """

    importer: str
    target: str
    name: str | None
    path: str
    line: int

    def where(self) -> str:
        return f"{self.path}:{self.line}"


def module_name(path: Path, root: Path) -> str:
    """The dotted name of the module in ``path`` (a package's ``__init__.py`` is the package)."""
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_of(path: Path, root: Path) -> str:
    """The package that relative imports in ``path`` are resolved against."""
    return ".".join(path.relative_to(root).with_suffix("").parts[:-1])


def _resolved(node: ast.ImportFrom, package: str) -> str:
    if not node.level:
        return node.module or ""
    parts = package.split(".") if package else []
    base = parts[: len(parts) - node.level + 1]
    return ".".join([*base, node.module] if node.module else base)


def import_statements(path: Path, root: Path) -> Iterator[tuple[str, str | None, int]]:
    """``(module, name, line)`` for every import in ``path``, at any depth, relative ones resolved.

    ``import a.b`` gives ``("a.b", None, line)``; ``from a import b, c`` gives
    ``("a", "b", line)`` and ``("a", "c", line)``.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = package_of(path, root)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, None, node.lineno
        elif isinstance(node, ast.ImportFrom):
            module = _resolved(node, package)
            for alias in node.names:
                yield module, alias.name, node.lineno


def imported_modules(path: Path, root: Path = ROOT) -> set[str]:
    """Every module name ``path`` imports: each ``from`` module, and ``module.name`` for its names."""
    names: set[str] = set()
    for module, name, _ in import_statements(path, root):
        names.add(module)
        if name is not None:
            names.add(f"{module}.{name}")
    return names


def package_modules(root: Path, packages: Sequence[str] = SHIPPED_PACKAGES) -> dict[str, Path]:
    """Every module of ``packages`` under ``root``, by dotted name."""
    found: dict[str, Path] = {}
    for package in packages:
        folder = root / package
        if folder.is_dir():
            found.update((module_name(p, root), p) for p in sorted(folder.rglob("*.py")))
    return found


def import_edges(root: Path, modules: dict[str, Path]) -> list[ImportEdge]:
    """The project imports of every module in ``modules``, each resolved to the module it runs."""
    edges: list[ImportEdge] = []
    for importer, path in modules.items():
        where = path.relative_to(root).as_posix()
        for module, name, line in import_statements(path, root):
            submodule = f"{module}.{name}" if name is not None else None
            target = submodule if submodule in modules else module
            edges.append(ImportEdge(importer, target, name if target == module else None, where, line))
    return edges


def _strongly_connected(nodes: Iterable[str], successors: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components, iterative (no recursion limit)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []
    for start in nodes:
        if start in index:
            continue
        work: list[tuple[str, Iterator[str]]] = [(start, iter(sorted(successors.get(start, ()))))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(successors.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                components.append(sorted(component))
    return components


def import_cycles(root: Path, modules: dict[str, Path]) -> list[list[ImportEdge]]:
    """The edges inside each import cycle: components of more than one module, and self-imports."""
    edges = [e for e in import_edges(root, modules) if e.target in modules]
    successors: dict[str, set[str]] = {}
    for edge in edges:
        successors.setdefault(edge.importer, set()).add(edge.target)
    cycles = []
    for component in _strongly_connected(sorted(modules), successors):
        members = set(component)
        inside = [e for e in edges if e.importer in members and e.target in members]
        if len(component) > 1 or inside:
            cycles.append(sorted(inside, key=lambda e: (e.importer, e.line, e.target)))
    return cycles


def _is_private(part: str) -> bool:
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def private_imports(root: Path, modules: dict[str, Path]) -> list[ImportEdge]:
    """Imports of a private name or module of another top-level project package."""
    project = {name.split(".")[0] for name in modules}
    found = []
    for edge in import_edges(root, modules):
        top = edge.target.split(".")[0]
        if top not in project or top == edge.importer.split(".")[0]:
            continue
        parts = [*edge.target.split("."), *([edge.name] if edge.name else [])]
        if any(_is_private(part) for part in parts):
            found.append(edge)
    return found


def long_modules(root: Path, modules: dict[str, Path], limit: int = MAX_MODULE_LINES) -> list[tuple[str, int]]:
    """``(path, lines)`` of each module over ``limit`` lines, the allowed ones left out."""
    found = []
    for path in modules.values():
        where = path.relative_to(root).as_posix()
        lines = len(path.read_text(encoding="utf-8").splitlines())
        if lines > limit and where not in LONG_MODULES_ALLOWED:
            found.append((where, lines))
    return found


def _is_parser_builder(name: str) -> bool:
    return name.startswith(PARSER_BUILDER_PREFIXES)


def long_functions(root: Path, modules: dict[str, Path], limit: int = MAX_FUNCTION_LINES) -> list[tuple[str, str, int]]:
    """``(path:line, name, lines)`` of each function over ``limit`` lines (``def`` to its last line)."""
    found = []
    for path in modules.values():
        where = path.relative_to(root).as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) or _is_parser_builder(node.name):
                continue
            lines = (node.end_lineno or node.lineno) - node.lineno + 1
            if lines > limit:
                found.append((f"{where}:{node.lineno}", node.name, lines))
    return sorted(found)


def problems(root: Path = ROOT, packages: Sequence[str] = SHIPPED_PACKAGES) -> list[str]:
    """Every layering problem under ``root``, one readable paragraph each (empty when clean)."""
    modules = package_modules(root, packages)
    report = []
    for cycle in import_cycles(root, modules):
        members = sorted({e.importer for e in cycle})
        closing = "\n".join(f"    {e.importer} -> {e.target} ({e.where()})" for e in cycle)
        report.append(f"import cycle between {', '.join(members)}:\n{closing}")
    for edge in private_imports(root, modules):
        what = f"{edge.target}.{edge.name}" if edge.name else edge.target
        report.append(f"private import of another package: {edge.importer} imports {what} ({edge.where()})")
    for where, lines in long_modules(root, modules):
        report.append(f"module over {MAX_MODULE_LINES} lines: {where} has {lines}")
    for where, name, lines in long_functions(root, modules):
        report.append(f"function over {MAX_FUNCTION_LINES} lines: {name} ({where}) has {lines}")
    return report


def main(argv: Sequence[str] | None = None, packages: Sequence[str] = SHIPPED_PACKAGES) -> int:
    """The command: print what :func:`problems` finds under ``--root``; 0 when clean, 1 otherwise."""
    parser = argparse.ArgumentParser(prog="python -m tests.check_layering", description=__doc__.split("\n")[0])
    parser.add_argument("--root", type=Path, default=ROOT, help="the repository root (default: this checkout)")
    args = parser.parse_args(argv)
    found = problems(args.root.resolve(), packages)
    if not found:
        print(f"layering check: clean ({', '.join(packages)})")
        return 0
    print(f"layering check: {len(found)} problem(s)", file=sys.stderr)
    for line in found:
        print(f"- {line}", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())

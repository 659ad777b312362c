"""The guides stay true to the tree, and every citation key resolves.

- docs/architecture.md is a page a newcomer reads in ten minutes: under ``MAX_LINES`` lines;
- every module path named in docs/architecture.md and docs/measurements.md exists: a path
  with a folder (``rcwa/table/store.py``) from the repository root, a bare file name
  (``lamellar.cpp``) somewhere in the tree; every dotted module name in backticks whose
  first part is a project package (``rcwa.table.store``, ``rcwa.solver.STACK_METHODS``)
  names a module, and what follows the module a name that module defines or imports;
- every bracketed key ``[Name YEARx...]`` in the docstrings and comments of the code
  (rcwa/ with rcwa/cpp/, renderer/, calibration/, reports/, datasets_synthetic/,
  workbench/, benchmarks/) is an entry of docs/references.md.
"""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MAX_LINES = 250
CHECKED_GUIDES = ("docs/architecture.md", "docs/measurements.md")
PACKAGES = ("rcwa", "renderer", "calibration", "datasets_synthetic", "reports", "workbench", "benchmarks", "tests")
CITING_FOLDERS = ("rcwa", "renderer", "calibration", "reports", "datasets_synthetic", "workbench", "benchmarks")
SOURCE_SUFFIXES = (".py", ".cpp", ".hpp")

MODULE_PATH = re.compile(r"(?<![\w/.-])[a-z_]+(?:/[a-z_0-9]+)*\.(?:py|hpp|cpp)\b")
DOTTED_NAME = re.compile(r"`([a-z_]+(?:\.[A-Za-z_][A-Za-z_0-9]*)+)`")
# A citation: [Moharam 1995a], [Moharam 1995a, Eq. 12], [Bai 2005a; Li 1997]; a key is
# words (capitalised, with hyphens or a slash: SCHOTT TIE-29, IEC 61966-2-1, TIFF/EP) then a year.
KEY = r"[A-Z][\w/-]*(?: [A-Z\d][\w/.-]*)*? \d{4}[a-z]?\b"
CITATION = re.compile(rf"\[({KEY}(?:[^\]\[]*?;\s*{KEY})*)[^\]\[]*\]")
ENTRY = re.compile(r"^- \*\*\[([^\]]+)\]\*\*", re.MULTILINE)


def _lines(guide: str) -> list[str]:
    return (ROOT / guide).read_text(encoding="utf-8").splitlines()


@cache
def _tree_file_names() -> frozenset[str]:
    return frozenset(p.name for folder in PACKAGES for p in (ROOT / folder).rglob("*")
                     if p.suffix in SOURCE_SUFFIXES)


def _module_file(parts: list[str]) -> Path | None:
    """The file of the dotted module ``parts`` (a package's ``__init__.py``), or None."""
    base = ROOT.joinpath(*parts)
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _defined_names(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(t.id for t in targets if isinstance(t, ast.Name))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((alias.asname or alias.name).split(".")[0] for alias in node.names)
    return names


def dotted_name_problem(dotted: str) -> str | None:
    """Why ``dotted`` does not name a module (and a name in it) of the tree; None when it does."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        path = _module_file(parts[:cut])
        if path is None:
            continue
        rest = parts[cut:]
        if rest and rest[0] not in _defined_names(path):
            return f"{'.'.join(parts[:cut])} defines no {rest[0]}"
        return None
    return "no such module"


def test_architecture_is_a_page_a_newcomer_reads() -> None:
    count = len(_lines("docs/architecture.md"))
    assert count < MAX_LINES, f"docs/architecture.md has {count} lines; the bar is under {MAX_LINES}"


@pytest.mark.parametrize("guide", CHECKED_GUIDES)
def test_every_module_path_named_exists(guide: str) -> None:
    missing: list[str] = []
    for number, line in enumerate(_lines(guide), 1):
        for path in MODULE_PATH.findall(line):
            exists = (ROOT / path).is_file() if "/" in path else path in _tree_file_names()
            if not exists:
                missing.append(f"{guide}:{number}: {path}")
    assert not missing, "module paths that are not in the tree:\n" + "\n".join(missing)


@pytest.mark.parametrize("guide", CHECKED_GUIDES)
def test_every_dotted_module_name_exists(guide: str) -> None:
    text = (ROOT / guide).read_text(encoding="utf-8")
    problems = [f"{guide}: `{name}`: {why}" for name in sorted(set(DOTTED_NAME.findall(text)))
                if name.split(".")[0] in PACKAGES and (why := dotted_name_problem(name))]
    assert not problems, "dotted names that are not in the tree:\n" + "\n".join(problems)


def reference_keys() -> set[str]:
    return set(ENTRY.findall((ROOT / "docs/references.md").read_text(encoding="utf-8")))


def cited_keys(text: str) -> list[str]:
    """Every key cited in brackets in ``text``: ``[Li 1997, Eqs. 38-39; Li 1996]`` gives both."""
    keys: list[str] = []
    for match in CITATION.finditer(text):
        keys.extend(re.findall(KEY, match.group(0)))
    return keys


def test_citation_pattern() -> None:
    assert cited_keys("(see [Moharam 1995a, Eq. 12] and [Bai 2005a; Li 1997])") == [
        "Moharam 1995a", "Bai 2005a", "Li 1997"]
    assert cited_keys("[SCHOTT TIE-29] [IEC 61966-2-1] [Garrido-Jurado 2014, Sec. 3]") == ["Garrido-Jurado 2014"]
    assert cited_keys("x[m, n] = c(n - m); [[eps]]; [0, 1]; [Exx Exy; Eyx Eyy]") == []


def test_every_cited_key_is_in_the_references() -> None:
    known = reference_keys()
    assert "Moharam 1995a" in known, "docs/references.md's entries are not read"
    unknown: list[str] = []
    for folder in CITING_FOLDERS:
        for path in sorted((ROOT / folder).rglob("*")):
            if path.suffix not in SOURCE_SUFFIXES:
                continue
            text = path.read_text(encoding="utf-8")
            unknown.extend(f"{path.relative_to(ROOT)}: [{key}]" for key in cited_keys(text) if key not in known)
    assert not unknown, "citation keys with no entry in docs/references.md:\n" + "\n".join(unknown)

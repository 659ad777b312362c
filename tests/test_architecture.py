"""The package layering, checked on the source: who may import whom.

- ``workbench.core`` (the shared kernel) imports no project package but itself;
- the libraries (rcwa, renderer, calibration, datasets_synthetic, reports) never import
  the face (``workbench`` outside ``workbench.core``: the CLI, the demo, the planner);
- calibration never sees how synthetic photos are made, and the synthetic datasets'
  truth never comes from the calibration code (neither imports the other);
- benchmarks live in ``benchmarks/`` only: the wheel's packages (pyproject.toml) hold no
  ``bench_*`` module and do not import ``benchmarks``, which is not shipped.

Imports are read with ``ast`` from every module, including imports inside functions, so a
late ``from workbench.cli import main`` is caught as well as a top-level one (the scanner
of ``tests/check_layering.py``, which ``make check`` runs for cycles and private imports).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from tests import check_layering

ROOT = Path(__file__).resolve().parents[1]
PROJECT_PACKAGES = ("workbench", "rcwa", "renderer", "calibration", "datasets_synthetic", "reports")
LIBRARIES = ("rcwa", "renderer", "calibration", "datasets_synthetic", "reports")
FORBIDDEN_PAIRS = {"calibration": ("datasets_synthetic",), "datasets_synthetic": ("calibration",)}


def imported_modules(path: Path) -> set[str]:
    """Every module name ``path`` imports (absolute, and relative ones resolved): the layering check's scanner."""
    return check_layering.imported_modules(path, ROOT)


def modules_of(package: str) -> list[Path]:
    folder = ROOT / package
    return sorted(folder.rglob("*.py")) if folder.is_dir() else []


def _is_face(module: str) -> bool:
    return (module == "workbench" or module.startswith("workbench.")) and not (
        module == "workbench.core" or module.startswith("workbench.core."))


@pytest.mark.parametrize("package", LIBRARIES)
def test_libraries_never_import_the_face(package: str) -> None:
    offenders = {str(p.relative_to(ROOT)): sorted(m for m in imported_modules(p) if _is_face(m))
                 for p in modules_of(package)}
    offenders = {k: v for k, v in offenders.items() if v}
    assert not offenders, f"library modules importing workbench's command-line face: {offenders}"


def test_shared_kernel_imports_no_project_package() -> None:
    files = modules_of("workbench/core")
    assert files, "workbench/core is missing"
    offenders = {}
    for path in files:
        bad = sorted(m for m in imported_modules(path)
                     if m.split(".")[0] in PROJECT_PACKAGES and not m.startswith("workbench.core"))
        if bad:
            offenders[str(path.relative_to(ROOT))] = bad
    assert not offenders, f"the shared kernel imports project packages: {offenders}"


@pytest.mark.parametrize(("package", "forbidden"), sorted(FORBIDDEN_PAIRS.items()))
def test_calibration_and_synthetic_data_stay_apart(package: str, forbidden: tuple[str, ...]) -> None:
    offenders = {str(p.relative_to(ROOT)): sorted(m for m in imported_modules(p) if m.split(".")[0] in forbidden)
                 for p in modules_of(package)}
    offenders = {k: v for k, v in offenders.items() if v}
    assert not offenders, f"{package} imports {forbidden}: {offenders}"


def shipped_packages() -> list[str]:
    """The packages the wheel installs (pyproject.toml, scikit-build-core's wheel.packages)."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return list(config["tool"]["scikit-build"]["wheel"]["packages"])


def test_the_wheel_ships_every_library_and_no_benchmark() -> None:
    packages = shipped_packages()
    assert set(LIBRARIES) | {"workbench"} <= set(packages), packages
    assert "benchmarks" not in packages and "tests" not in packages, packages
    bench_modules = [str(p.relative_to(ROOT)) for package in packages for p in modules_of(package)
                     if p.name.startswith("bench")]
    assert not bench_modules, f"benchmarks inside shipped packages (move them to benchmarks/): {bench_modules}"
    importing = {str(p.relative_to(ROOT)): sorted(m for m in imported_modules(p) if m.split(".")[0] == "benchmarks")
                 for package in packages for p in modules_of(package)}
    importing = {k: v for k, v in importing.items() if v}
    assert not importing, f"shipped modules importing benchmarks/, which the wheel does not hold: {importing}"


def test_the_check_sees_a_violation(tmp_path: Path) -> None:
    """The scanner itself: a function-level import of the CLI is found."""
    module = ROOT / "rcwa" / "_architecture_probe.py"
    try:
        module.write_text("def f():\n    from workbench.cli import main\n    from ..workbench import demo\n")
        found = imported_modules(module)
    finally:
        module.unlink()
    assert "workbench.cli" in found and any(_is_face(m) for m in found)

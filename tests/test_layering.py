"""The layering check (tests/check_layering.py) on small probe trees written to tmp_path.

Each probe is a clean tree of two top-level packages (``alpha``, ``beta``) with one problem
added; the check must name it, and must accept the clean tree. The real tree is checked by
``make check`` (``python -m tests.check_layering``), not here.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests import check_layering

PACKAGES = ("alpha", "beta")
CLEAN = {
    "alpha/__init__.py": "from alpha.core import value\n",
    "alpha/core.py": "import math\n\n\ndef value() -> float:\n    return math.pi\n",
    "alpha/_private.py": "SECRET = 1\n",
    "alpha/user.py": "from alpha import _private\nfrom alpha.core import value\nfrom . import core\n",
    "beta/__init__.py": "",
    "beta/helper.py": "",
    "beta/consumer.py": ("from . import helper\n\n\n"
                         "def f():\n    from alpha import value\n    from alpha import core\n    return value, core, helper\n"),
}


def write_tree(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root


def problems_with(root: Path, changes: dict[str, str]) -> list[str]:
    return check_layering.problems(write_tree(root, {**CLEAN, **changes}), PACKAGES)


def function_of(lines: int, name: str = "f") -> str:
    """A function ``lines`` long from its ``def`` to its last line."""
    return f"def {name}():\n" + "    x = 0\n" * (lines - 2) + "    return x\n"


def test_a_clean_probe_passes(tmp_path: Path) -> None:
    assert problems_with(tmp_path, {}) == []


def test_a_cycle_is_found_with_the_edges_that_close_it(tmp_path: Path) -> None:
    found = problems_with(tmp_path, {
        "alpha/core.py": "def value():\n    from alpha.user import value as again\n    return again\n",
    })
    assert len(found) == 1 and found[0].startswith("import cycle between alpha.core, alpha.user"), found
    assert "alpha.core -> alpha.user (alpha/core.py:2)" in found[0], found
    assert "alpha.user -> alpha.core (alpha/user.py:2)" in found[0], found


def test_a_cycle_through_a_package_init_and_a_submodule_named_in_from_import(tmp_path: Path) -> None:
    """``from alpha import value`` runs alpha/__init__, which imports alpha.core; ``from beta import
    consumer`` imports the submodule beta.consumer."""
    found = problems_with(tmp_path, {
        "alpha/core.py": "from beta import consumer\n\n\ndef value():\n    return consumer\n",
    })
    assert len(found) == 1 and found[0].startswith("import cycle between alpha, alpha.core, beta.consumer"), found
    assert "alpha.core -> beta.consumer (alpha/core.py:1)" in found[0], found
    assert "beta.consumer -> alpha (beta/consumer.py:5)" in found[0], found


def test_a_cycle_of_relative_imports_is_resolved(tmp_path: Path) -> None:
    found = problems_with(tmp_path, {"beta/helper.py": "from .consumer import f\n"})
    assert len(found) == 1 and "beta.consumer -> beta.helper (beta/consumer.py:1)" in found[0], found
    assert "beta.helper -> beta.consumer (beta/helper.py:1)" in found[0], found


def test_a_module_importing_itself_is_a_cycle(tmp_path: Path) -> None:
    found = problems_with(tmp_path, {"beta/loop.py": "def f():\n    from beta import loop\n    return loop\n"})
    assert found == ["import cycle between beta.loop:\n    beta.loop -> beta.loop (beta/loop.py:2)"], found


@pytest.mark.parametrize("statement", [
    "from alpha._private import SECRET",
    "from alpha.core import _helper",
    "import alpha._private",
    "from alpha import _private",
])
def test_a_private_import_of_another_package_is_found(tmp_path: Path, statement: str) -> None:
    found = problems_with(tmp_path, {"beta/consumer.py": f"def f():\n    {statement}\n"})
    assert len(found) == 1 and found[0].startswith("private import of another package: beta.consumer imports"), found
    assert found[0].endswith("(beta/consumer.py:2)"), found


def test_a_long_module_is_found(tmp_path: Path) -> None:
    lines = check_layering.MAX_MODULE_LINES + 1
    found = problems_with(tmp_path, {"beta/long.py": "x = 0\n" * lines})
    assert found == [f"module over {check_layering.MAX_MODULE_LINES} lines: beta/long.py has {lines}"], found
    assert problems_with(tmp_path, {"beta/long.py": "x = 0\n" * (lines - 1)}) == []


def test_a_long_function_is_found_and_a_parser_builder_is_not(tmp_path: Path) -> None:
    lines = check_layering.MAX_FUNCTION_LINES + 1
    found = problems_with(tmp_path, {"beta/long.py": "\n\n" + function_of(lines, "long_one")})
    assert found == [f"function over {check_layering.MAX_FUNCTION_LINES} lines: long_one (beta/long.py:3) has {lines}"]
    builders = "".join(function_of(lines, name) for name in ("add_parsers", "_build_parser", "add_arguments"))
    short = function_of(lines - 1, "just_short_enough")
    assert problems_with(tmp_path, {"beta/long.py": builders + short}) == []


def test_the_command_exits_zero_when_clean_and_one_with_a_list(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_tree(tmp_path, CLEAN)
    assert check_layering.main(["--root", str(tmp_path)], PACKAGES) == 0
    write_tree(tmp_path, {"beta/consumer.py": "import alpha._private\n"})
    assert check_layering.main(["--root", str(tmp_path)], PACKAGES) == 1
    assert "- private import of another package: beta.consumer imports alpha._private" in capsys.readouterr().err

"""Every command and option of the command line explains itself (issue 13): a help line
for each subcommand and each argument, and `--version`."""

from __future__ import annotations

import argparse

import pytest

from workbench import __version__
from workbench.cli import _build_parser, main


def _parsers(parser: argparse.ArgumentParser, path: str = "workbench"):
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help for choice in action._choices_actions}
            for name, sub in action.choices.items():
                assert helps.get(name), f"'{path} {name}' has no help line in '{path} --help'"
                yield from _parsers(sub, f"{path} {name}")


def test_every_option_of_every_command_has_help() -> None:
    missing = []
    for path, parser in _parsers(_build_parser()):
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._VersionAction, argparse._SubParsersAction)):
                continue
            if not action.help:
                missing.append(f"{path} {'/'.join(action.option_strings) or action.dest}")
    assert not missing, f"arguments without help: {missing}"


def test_every_option_that_takes_a_value_says_its_default() -> None:
    """An option that may be left out says what happens then: its help, as --help shows it,
    holds "default" (the formatter adds the value where there is one; options without a
    value, such as --preset draft's --spp, say "default: the preset's" and the like).
    Flags (store_true), required options and repeatable ones defaulting to none are exempt."""
    missing = []
    for path, parser in _parsers(_build_parser()):
        formatter = parser._get_formatter()
        for action in parser._actions:
            if (not action.option_strings or action.required or action.nargs == 0
                    or isinstance(action, (argparse._HelpAction, argparse._VersionAction))):
                continue
            if isinstance(action, argparse._AppendAction) and action.default == []:
                continue
            shown = formatter._expand_help(action) if action.help else ""
            if "default" not in shown:
                missing.append(f"{path} {'/'.join(action.option_strings)}")
    assert not missing, f"options whose help does not say the default: {missing}"


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out.strip() == f"workbench {__version__}"


@pytest.mark.parametrize("quiet", [False, True])
@pytest.mark.parametrize(("argv", "module", "function", "result"), [
    (["study", "rcwa", "cd"], "rcwa.table_study", "run_study", {"presets": []}),
    (["study", "render", "cornell_cd"], "renderer.render_study", "run_render_study", {"energy": []}),
])
def test_the_studies_show_progress_unless_quiet(argv, module, function, result, quiet, tmp_path, monkeypatch) -> None:
    """The studies run for minutes: the command asks them for a progress bar, --quiet turns it off."""
    import importlib

    asked: list[bool] = []

    def study(*args, progress: bool = True, **kwargs) -> dict:
        asked.append(progress)
        return result

    monkeypatch.setattr(importlib.import_module(module), function, study)
    assert main([*argv, "--out", str(tmp_path), *(["--quiet"] if quiet else [])]) == 0
    assert asked == [not quiet]

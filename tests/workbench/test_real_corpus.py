"""Every real file in ../shared/data/real through the commands that take a file of its kind: a right
answer or one `error:` line, never a traceback (issue 45, item 2's corpus test).

Photos and board views are decoded; the text files beside them (the publishers' calibrations)
must be refused in one line as images, as scenes and as structures.
"""

from __future__ import annotations

import traceback
from pathlib import Path

import pytest

from workbench.cli import main

REAL = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"
FILES = sorted(p for p in REAL.rglob("*") if p.is_file()) if REAL.is_dir() else []
IMAGES = {".jpg", ".jpeg", ".png", ".tif", ".tiff", ".dng", ".exr"}

pytestmark = pytest.mark.skipif(not FILES, reason="../shared/data/real is not beside the checkout")


def _run(args: list[str], capsys) -> tuple[int, str]:
    try:
        code = main(args)
    except SystemExit as exit_:  # argparse's own refusals
        code = int(exit_.code or 0)
    except Exception:  # noqa: BLE001 - what the test is for: any traceback is a failure, shown whole
        pytest.fail(f"{' '.join(args)}: traceback\n{traceback.format_exc()}")
    return code, capsys.readouterr().err


@pytest.mark.parametrize("path", FILES, ids=[str(p.relative_to(REAL)) if FILES else "" for p in FILES])
def test_every_real_file_decodes_or_is_refused_in_one_line(path, tmp_path, capsys):
    code, err = _run(["decode", str(path), "--out", str(tmp_path / "x.exr")], capsys)
    if path.suffix.lower() in IMAGES:
        assert code == 0 and (tmp_path / "x.exr").is_file(), err
    else:
        assert code == 2 and err.startswith("error: ") and err.strip().count("\n") == 0, err


@pytest.mark.parametrize("path", [p for p in FILES if p.suffix.lower() not in IMAGES])
def test_real_text_files_are_no_scene_or_structure(path, tmp_path, capsys):
    for args in (["plan", str(path)], ["rcwa", "solve", str(path), "--wavelength", "550", "--orders", "5"]):
        code, err = _run(args, capsys)
        assert code == 2 and err.startswith("error: ") and err.strip().count("\n") == 0, err

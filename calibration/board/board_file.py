"""The board of a dataset's calibration views: DATASET/calibration/board.json.

A dataset carries the description of the board its calibration/ views show, so that
``calibrate DATASET`` needs no flags and cannot silently assume a board (``workbench
synth`` writes it; a person adds it beside real board photos)::

    {"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 20.0}
    {"kind": "charuco", "squares": [10, 7], "square_mm": 20.0, "dictionary": "DICT_5X5_100", "marker_mm": 15.0}

``inner_corners`` is OpenCV's patternSize (columns, rows of inner corners); a ChArUco
board is counted in squares, as OpenCV's CharucoBoard counts it. ``format`` and ``note``
may be present too; any other field is refused (a misspelt one would otherwise be
ignored). ``--board`` and ``--square-mm`` on the command line override the file, and the
result says so; with neither, board views are an error (``resolve_board``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

from calibration.board.charuco import parse_charuco
from workbench.core.errors import UserInputError

BOARD_FILE = "board.json"
KINDS = ("checkerboard", "charuco")
OPTIONAL_FIELDS = {"format", "note"}
FIELDS = {"checkerboard": {"kind", "inner_corners", "square_mm"},
          "charuco": {"kind", "squares", "square_mm", "dictionary", "marker_mm"}}
EXAMPLE = '{"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 20}'


@dataclass(frozen=True)
class BoardSpec:
    """A calibration board: ``size`` is (cols, rows) of inner corners for a checkerboard, of
    squares for a ChArUco board; ``source`` says where each value came from."""

    kind: str
    size: tuple[int, int]
    square_mm: float
    dictionary: str | None = None
    marker_mm: float | None = None
    source: str = ""
    overridden: tuple[str, ...] = ()

    def charuco(self):
        """calibration.board.charuco.CharucoSpec, or None for a checkerboard."""
        if self.kind != "charuco":
            return None
        return parse_charuco(f"{self.dictionary},{self.marker_mm}", where="dictionary")

    def describe(self) -> str:
        what = (f"{self.size[0]}x{self.size[1]} inner corners" if self.kind == "checkerboard"
                else f"ChArUco {self.size[0]}x{self.size[1]} squares, {self.dictionary}, {self.marker_mm:g} mm markers")
        return f"{self.kind}: {what}, {self.square_mm:g} mm squares ({self.source})"

    def to_json(self) -> dict:
        counts = "inner_corners" if self.kind == "checkerboard" else "squares"
        record: dict = {"kind": self.kind, counts: list(self.size), "square_mm": self.square_mm}
        if self.kind == "charuco":
            record |= {"dictionary": self.dictionary, "marker_mm": self.marker_mm}
        return record | {"source": self.source, "overridden_by_command_line": list(self.overridden)}


def _pair(value, path: Path, field: str, least: int) -> tuple[int, int]:
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) and v >= least for v in value)):
        raise UserInputError(f"must be two integers of at least {least}", file=path, field=field,
                             expected="[columns, rows]", got=value)
    return value[0], value[1]


def _positive(value, path: Path, field: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise UserInputError("must be a positive number (millimetres)", file=path, field=field, got=value)
    return float(value)


def read_board_file(path: str | Path) -> BoardSpec:
    """board.json, checked: every error names the file and the field."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise UserInputError(f"cannot be read ({exc})", file=path, expected=EXAMPLE) from None
    except ValueError as exc:
        raise UserInputError(f"is not JSON ({exc})", file=path, expected=EXAMPLE) from None
    if not isinstance(data, dict):
        raise UserInputError("is not a board description", file=path, expected=f"a JSON object such as {EXAMPLE}")
    kind = data.get("kind")
    if kind not in KINDS:
        raise UserInputError("unknown board kind" if "kind" in data else "is missing", file=path, field="kind",
                             expected=" or ".join(f'"{k}"' for k in KINDS), got=kind)
    unknown = sorted(set(data) - FIELDS[kind] - OPTIONAL_FIELDS)
    if unknown:
        raise UserInputError(f"unknown field for a {kind}", file=path, field=unknown[0],
                             expected=f"only {', '.join(sorted(FIELDS[kind]))}")
    for field in sorted(FIELDS[kind]):
        if field not in data:
            raise UserInputError("is missing", file=path, field=field, expected=f"a {kind} board: {EXAMPLE}"
                                 if kind == "checkerboard" else "squares, square_mm, dictionary, marker_mm")
    square = _positive(data["square_mm"], path, "square_mm")
    if kind == "checkerboard":
        return BoardSpec(kind, _pair(data["inner_corners"], path, "inner_corners", 2), square, source=str(path))
    marker = _positive(data["marker_mm"], path, "marker_mm")
    if marker >= square:
        raise UserInputError("a marker must be smaller than its square", file=path, field="marker_mm",
                             expected=f"less than square_mm ({square:g})", got=marker)
    if not isinstance(data["dictionary"], str):
        raise UserInputError("must be an OpenCV dictionary name", file=path, field="dictionary", got=data["dictionary"])
    spec = BoardSpec(kind, _pair(data["squares"], path, "squares", 3), square, data["dictionary"], marker, str(path))
    try:
        spec.charuco()
    except UserInputError as exc:
        raise UserInputError(exc.reason, file=path, field="dictionary", expected=exc.expected, got=data["dictionary"]) from None
    return spec


def resolve_board(calibration_folder: Path, board: tuple[int, int] | None, square_mm: float | None) -> BoardSpec:
    """The board of the views in ``calibration_folder``: its board.json, with ``board`` and
    ``square_mm`` (the command line's ``--board``, ``--square-mm``) overriding it; without
    board.json both flags are needed."""
    path = calibration_folder / BOARD_FILE
    if not path.exists():
        if board is None or square_mm is None:
            missing = " and ".join(f for f, v in (("--board COLSxROWS", board), ("--square-mm S", square_mm)) if v is None)
            raise UserInputError("the board of the calibration views is not described", file=path,
                                 expected=f"{path} ({EXAMPLE}), or {missing} on the command line")
        return BoardSpec("checkerboard", (int(board[0]), int(board[1])), float(square_mm), source="command line")
    spec = read_board_file(path)
    changes: dict = {}
    if board is not None and tuple(board) != spec.size:
        changes["size"] = (int(board[0]), int(board[1]))
    if square_mm is not None and float(square_mm) != spec.square_mm:
        changes["square_mm"] = float(square_mm)
    if not changes:
        return spec
    flags = tuple({"size": "--board", "square_mm": "--square-mm"}[k] for k in changes)
    return replace(spec, **changes, overridden=flags, source=f"{path}, overridden by {' and '.join(flags)}")

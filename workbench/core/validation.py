"""Field validation shared by every file format (structures, scenes): each failure is a
UserInputError naming the field and what was expected; callers add the file."""

from __future__ import annotations

import math
import stat
from pathlib import Path
from typing import Any

from workbench.core.errors import UserInputError


def required(table: dict[str, Any], key: str, where: str) -> Any:
    if key not in table:
        raise UserInputError("is missing", field=f"{where}{key}")
    return table[key]


def reject_unknown(table: dict[str, Any], known: set[str], where: str) -> None:
    for key in table:
        if key not in known:
            raise UserInputError("unknown field", field=f"{where}{key}", expected=f"one of {sorted(known)}")


def number(value: Any, where: str, *, positive: bool = False, nonnegative: bool = False,
           at_least: float | None = None, at_most: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserInputError("must be a number", field=where, got=value)
    try:
        x = float(value)
    except OverflowError:  # a TOML integer beyond a float's range
        raise UserInputError("must be a finite number", field=where, got=value) from None
    if not math.isfinite(x):  # TOML's inf and nan: no length, position or power is infinite or undefined
        raise UserInputError("must be a finite number", field=where, got=value)
    if positive and not x > 0:
        raise UserInputError("must be positive", field=where, expected="a number > 0", got=value)
    if nonnegative and not x >= 0:
        raise UserInputError("must not be negative", field=where, expected="a number >= 0", got=value)
    if at_least is not None and not x >= at_least:
        raise UserInputError("is too small", field=where, expected=f"a number >= {at_least:g}", got=value)
    if at_most is not None and not x <= at_most:
        raise UserInputError("is too large", field=where, expected=f"a number <= {at_most:g}", got=value)
    return x


def vector(value: Any, where: str, length: int, *, positive: bool = False) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != length:
        names = {2: "[a, b]", 3: "[x, y, z]"}.get(length, f"{length} numbers")
        raise UserInputError(f"must be a list of {length} numbers", field=where, expected=names, got=value)
    return tuple(number(v, f"{where}[{i}]", positive=positive) for i, v in enumerate(value))


def pair(value: Any, where: str, *, positive: bool = False) -> tuple[float, float]:
    a, b = vector(value, where, 2, positive=positive)
    return a, b


def point(value: Any, where: str) -> tuple[float, float, float]:
    """A position or direction ``[x, y, z]``."""
    x, y, z = vector(value, where, 3)
    return x, y, z


def read_text_file(path: str | Path, what: str) -> str:
    """The UTF-8 text of the ``what`` file at ``path`` (for example ``"structure"``).

    Each way a user's file can be wrong is a UserInputError naming the file: not found,
    a folder, a device or pipe (``/dev/zero`` would be read forever), larger than ``MAX_TEXT_BYTES``,
    unreadable, not text (a binary file), or empty.
    """
    path = Path(path)
    if not path.exists():
        raise UserInputError(f"{what} file not found", file=path, expected=f"an existing {what} file (TOML)")
    if path.is_dir():
        raise UserInputError(f"is a folder, not a {what} file", file=path, expected=f"a {what} file (TOML)")
    return _decoded_text(read_limited(path, what), path, what)


MAX_TEXT_BYTES = 16 << 20  # a structure, scene or material file is kilobytes; a table of n, k a few megabytes


def read_limited(path: str | Path, what: str, limit: int = MAX_TEXT_BYTES) -> bytes:
    """A user's file's bytes, refused (UserInputError naming it) when it is not a regular file (a
    device, a pipe) or larger than ``limit``: read with the limit, so a file that grows is cut off too."""
    path = Path(path)
    try:
        if not stat.S_ISREG(path.stat().st_mode):
            raise UserInputError(f"is not a regular file (a device, pipe or socket), not a {what} file", file=path,
                                 expected=f"a {what} file")
        with path.open("rb") as handle:
            data = handle.read(limit + 1)
    except OSError as exc:
        raise UserInputError(f"cannot read the {what} file ({exc.strerror})", file=path) from None
    if len(data) > limit:
        raise UserInputError(f"the {what} file is larger than {limit >> 20} MiB", file=path,
                             expected=f"a {what} file of at most {limit >> 20} MiB")
    return data


def _decoded_text(data: bytes, path: Path, what: str) -> str:
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise UserInputError(f"not a text file: byte {data[exc.start]:#04x} at offset {exc.start} is not UTF-8",
                             file=path, expected=f"a {what} file in TOML (UTF-8 text)") from None
    if not any(line.strip() and not line.lstrip().startswith("#") for line in text.splitlines()):
        raise UserInputError(f"the {what} file is empty (nothing but blank lines and comments)", file=path,
                             expected=f"a {what} in TOML (docs/{what}_format.md)")
    return text


def looks_like_path(name: str) -> bool:
    """Whether a name given on the command line is meant as a file rather than a built-in."""
    return "/" in name or "\\" in name or Path(name).suffix != ""

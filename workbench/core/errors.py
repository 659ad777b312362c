"""User-facing errors.

Every error a user can cause (a bad file, a bad argument, a material outside its data
range) is raised as a :class:`UserInputError`. The command line prints its message and
exits with status 2, with no Python traceback. The message always says *where* (file and
field, or argument), *what was expected* and *what came*.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


class WorkbenchError(Exception):
    """Base class of every error the workbench raises on purpose."""


class UserInputError(WorkbenchError, ValueError):
    """Bad input from the user: a file, a field in it, or a command-line argument.

    Parameters
    ----------
    message:
        What is wrong, in words.
    file:
        The file the input came from, if any.
    field:
        The dotted path of the field inside the file (``layers[1].thickness``) or the
        argument name (``--orders``).
    expected:
        What would have been accepted.
    got:
        What came instead (its ``repr`` is shown).
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | Path | None = None,
        field: str | None = None,
        expected: str | None = None,
        got: Any = None,
    ) -> None:
        self.file = None if file is None else str(file)
        self.field = field
        self.expected = expected
        self.got = got
        self.reason = message
        super().__init__(self._format())

    def _format(self) -> str:
        where = []
        if self.file:
            where.append(self.file)
        if self.field:
            where.append(f"field '{self.field}'")
        text = (": ".join(where) + ": " if where else "") + self.reason
        if self.expected is not None:
            text += f"; expected {self.expected}"
        if self.got is not None:
            text += f", got {self.got!r}"
        return text

    def located(self, *, file: str | Path | None = None, field_prefix: str | None = None) -> "UserInputError":
        """Return a copy that also names the file and/or prefixes the field path.

        An error that already names another file (a CSV material a structure file refers
        to) keeps that file, where the mistake is, and says which file referred to it."""
        field = self.field
        if field_prefix:
            field = field_prefix if not field else f"{field_prefix}.{field}"
        reason, where = self.reason, file if file is not None else self.file
        if file is not None and self.file is not None and str(file) != self.file:
            reason, where = f"{self.reason} (referenced from {file})", self.file
        return UserInputError(reason, file=where, field=field, expected=self.expected, got=self.got)

"""Argument types (argparse ``type=``) and help texts shared by the command modules."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Collection, Iterable, Iterator
from typing import Any

SEED_MAX = 2**32 - 1  # Mitsuba's and numpy's seeds are unsigned 32-bit
SCENE_HELP = "a built-in scene (`workbench list scenes`) or a scene file (docs/scene_format.md)"
STRUCTURE_HELP = "a built-in structure (`workbench list structures`) or a structure file (docs/structure_format.md)"


class RegistryNames(Collection[str]):
    """The names of a registry (a dict of methods by name), read when argparse first needs them.

    As an option's choices (:func:`add_registry_option`), the option accepts exactly the
    registry's names and its help lists them in the registry's order, while the registry's
    module (``read`` imports it, and with it scipy) is imported only when that subcommand's
    help is shown or the option is given, not to build the parser: ``workbench --help`` and
    ``workbench list`` stay quick.
    """

    def __init__(self, read: Callable[[], Iterable[str]]) -> None:
        self._read = read
        self._names: tuple[str, ...] | None = None

    def _all(self) -> tuple[str, ...]:
        if self._names is None:
            self._names = tuple(self._read())
        return self._names

    def __contains__(self, name: object) -> bool:
        return name in self._all()

    def __iter__(self) -> Iterator[str]:
        return iter(self._all())

    def __len__(self) -> int:
        return len(self._all())


def add_registry_option(parser: argparse.ArgumentParser, flag: str, names: RegistryNames, **options: Any) -> None:
    """``parser.add_argument(flag, choices=names, **options)``, without reading ``names`` to add it
    (argparse formats a new argument's usage once, as a check, which would iterate its choices)."""
    action = parser.add_argument(flag, **options)
    action.choices = names


def _integer_pair(text: str, minimum: int, expected: str) -> tuple[int, int]:
    """``AxB`` with both integers at least ``minimum``; otherwise an error saying ``expected``."""
    try:
        a, b = (int(v) for v in text.lower().split("x"))
        if a < minimum or b < minimum:
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
    return a, b


def board_argument(text: str) -> tuple[int, int]:
    """``COLSxROWS``: a checkerboard's inner corners (or a ChArUco board's squares)."""
    return _integer_pair(text, 2, "COLSxROWS with integers >= 2 (e.g. 9x6)")


def count_argument(minimum: int, maximum: int | None = None) -> Callable[[str], int]:
    """An argparse type: an integer in [minimum, maximum], with the range in the error."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < minimum or (maximum is not None and value > maximum):
            bound = f"from {minimum} to {maximum}" if maximum is not None else f">= {minimum}"
            raise argparse.ArgumentTypeError(f"expected an integer {bound}, got {text!r}")
        return value

    return parse


def positive_number(kind: type[int] | type[float]) -> Callable[[str], float]:
    """An argparse type: a number of ``kind`` (int or float) greater than zero."""
    name = "integer" if kind is int else "number"

    def parse(text: str) -> float:
        try:
            value = kind(text)
            if not value > 0:
                raise ValueError
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a positive {name}, got {text!r}") from None
        return value

    return parse


def positive_numbers(kind: type[int] | type[float], name: str) -> Callable[[str], tuple[float, ...]]:
    """An argparse type: comma-separated positive numbers of ``kind`` (``name`` says what, in the error)."""

    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(kind(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated {name}, got {text!r}") from None
        if not values or not all(v > 0 for v in values):
            raise argparse.ArgumentTypeError(f"expected positive {name}, got {text!r}")
        return values

    return parse


def orders_argument(text: str) -> int | tuple[int, ...]:
    """``N`` or ``NX,NY``: retained harmonics (one count for both directions, or one each)."""
    parts = text.split(",")
    try:
        values = tuple(int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected N or NX,NY (odd integers), got {text!r}") from None
    return values[0] if len(values) == 1 else values


def resolution_argument(text: str) -> tuple[int, int]:
    """``WxH``: an image size in pixels."""
    return _integer_pair(text, 1, "WxH with positive integers (e.g. 640x480)")


def angle_range_argument(text: str) -> tuple[float, float]:
    """``LO,HI``: a range of angles in degrees."""
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LO,HI in degrees, got {text!r}") from None
    return lo, hi


def exposure_times_argument(text: str) -> list[float]:
    """``T,T,...``: exposure times in seconds, each positive."""
    try:
        values = [float(t) for t in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected exposure times in seconds, T,T,... (e.g. 1/250 as 0.004), got {text!r}") from None
    if any(not v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"exposure times must be positive, got {text!r}")
    return values

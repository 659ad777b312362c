"""Argument types shared by the command line's command groups (argparse ``type=``)."""

from __future__ import annotations

import argparse
from collections.abc import Callable


def board_argument(text: str) -> tuple[int, int]:
    """``COLSxROWS``: a checkerboard's inner corners (or a ChArUco board's squares)."""
    try:
        cols, rows = (int(v) for v in text.lower().split("x"))
        if cols < 2 or rows < 2:
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected COLSxROWS with integers >= 2 (e.g. 9x6), got {text!r}") from None
    return cols, rows


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

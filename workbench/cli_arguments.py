"""Argument types shared by the command line's command groups (argparse ``type=``)."""

from __future__ import annotations

import argparse


def board_argument(text: str) -> tuple[int, int]:
    """``COLSxROWS``: a checkerboard's inner corners (or a ChArUco board's squares)."""
    try:
        cols, rows = (int(v) for v in text.lower().split("x"))
        if cols < 2 or rows < 2:
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected COLSxROWS with integers >= 2 (e.g. 9x6), got {text!r}") from None
    return cols, rows

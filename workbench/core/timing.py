"""Wall-clock timing of one call, shared by the table builder, renders and benchmarks."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def timed(fn: Callable[..., T], *args) -> tuple[T, float]:
    """``fn(*args)`` and the seconds it took (module-level, so dask can ship it to workers)."""
    start = time.perf_counter()
    result = fn(*args)
    return result, time.perf_counter() - start

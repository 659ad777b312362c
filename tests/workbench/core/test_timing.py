"""Timing one call (workbench/core/timing.py): the result and the wall-clock seconds."""

from __future__ import annotations

import time

from workbench.core.timing import timed

SLEEP_S = 0.05
# time.sleep never returns early; the upper bound only guards against a unit error (ms for
# s would give 50), with room for a loaded 2-core machine.
UPPER_S = 2.0


def test_timed_returns_the_result_and_the_seconds_it_took():
    def add_slowly(a: int, b: int) -> int:
        time.sleep(SLEEP_S)
        return a + b

    result, seconds = timed(add_slowly, 2, 3)
    assert result == 5
    assert SLEEP_S <= seconds < UPPER_S

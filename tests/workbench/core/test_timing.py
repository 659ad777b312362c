"""Timing one call (workbench/core/timing.py): the result and the wall-clock seconds.

The clock is the module's own ``time.perf_counter``, replaced here by a scripted one, so
the seconds are exact and no real clock decides the outcome (issue 23: a test must pass on
a busy machine).
"""

from __future__ import annotations

from types import SimpleNamespace

from workbench.core import timing
from workbench.core.timing import timed


def test_timed_returns_the_result_and_the_seconds_between_its_two_clock_readings(monkeypatch):
    readings = iter([100.0, 100.25])
    calls: list[tuple[int, int]] = []
    monkeypatch.setattr(timing, "time", SimpleNamespace(perf_counter=lambda: next(readings)))

    def add(a: int, b: int) -> int:
        calls.append((a, b))
        return a + b

    result, seconds = timed(add, 2, 3)
    assert result == 5 and calls == [(2, 3)]
    assert seconds == 0.25
    assert next(readings, None) is None  # read exactly twice: before and after the call


def test_timed_reads_the_clock_around_the_call_not_before_it(monkeypatch):
    clock = SimpleNamespace(now=0.0)
    monkeypatch.setattr(timing, "time", SimpleNamespace(perf_counter=lambda: clock.now))

    def slow() -> str:
        clock.now += 7.0  # the call "takes" 7 s on the scripted clock
        return "done"

    assert timed(slow) == ("done", 7.0)

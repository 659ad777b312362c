"""Where independent work runs: here, or on a dask.distributed cluster.

``DaskExecutor`` is what ``workbench rcwa table``, ``workbench render`` and ``workbench
verify`` hand their chunks, photos and passes to when ``--scheduler`` or ``--workers`` is
given. It offers ``submit(fn, *args)`` returning futures, like ``concurrent.futures``.

A task that renders with Mitsuba is submitted with ``alone=True``: it runs under one lock per
worker process (``run_alone``), so a worker started with several threads still runs one
Mitsuba render at a time (Mitsuba's variant and Dr.Jit's thread pool are process-wide, and
two renders in one process would share that pool and sum their films in another order).
Table chunks need no lock: the solver's threads are its own.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from workbench.core.errors import UserInputError

_ALONE = threading.Lock()  # one per process: held by every ``alone`` task while it runs


def run_alone(fn: Callable[..., Any], *args: Any) -> Any:
    """``fn(*args)`` while this process runs no other ``alone`` task (the module's docstring)."""
    with _ALONE:
        return fn(*args)


class DaskExecutor:
    """Chunks on a dask.distributed cluster: an existing scheduler, or a LocalCluster.

    Each worker process runs one chunk at a time on one solver thread; results come back
    to this process, which alone writes the table (so atomic writes and resume work the
    same as locally).
    """

    def __init__(self, scheduler: str | None = None, workers: int | None = None) -> None:
        from distributed import Client, LocalCluster  # deferred: start-up time (only --scheduler/--workers need it)

        self._cluster = None
        self.submitted = 0  # tasks handed to the cluster so far (a verify run records each stage's)
        if scheduler:
            try:
                self._client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError) as exc:
                raise UserInputError(f"cannot reach the dask scheduler ({exc})", field="--scheduler", got=scheduler) from None
        else:
            self._cluster = LocalCluster(n_workers=workers or 2, threads_per_worker=1, processes=True,
                                         host="127.0.0.1", dashboard_address=None)
            self._client = Client(self._cluster)

    def submit(self, fn: Callable[..., Any], *args: Any, alone: bool = False) -> Any:
        """A future of ``fn(*args)`` on a worker; ``alone``: under the worker's Mitsuba lock (run_alone)."""
        self.submitted += 1
        if alone:
            return self._client.submit(run_alone, fn, *args, pure=False)
        return self._client.submit(fn, *args, pure=False)

    @property
    def workers(self) -> int:
        """How many workers the scheduler has now."""
        return len(self._client.scheduler_info().get("workers", {}))

    def close(self) -> None:
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()

    def __enter__(self) -> DaskExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

"""Where independent work runs: here, or on a dask.distributed cluster.

``DaskExecutor`` is what ``workbench rcwa table`` and ``workbench render`` (and the
verification run) hand their chunks and passes to when ``--scheduler`` or ``--workers``
is given. It offers ``submit(fn, *args)`` returning futures, like
``concurrent.futures``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from workbench.core.errors import UserInputError


class DaskExecutor:
    """Chunks on a dask.distributed cluster: an existing scheduler, or a LocalCluster.

    Each worker process runs one chunk at a time on one solver thread; results come back
    to this process, which alone writes the table (so atomic writes and resume work the
    same as locally).
    """

    def __init__(self, scheduler: str | None = None, workers: int | None = None) -> None:
        from distributed import Client, LocalCluster  # deferred: start-up time (only --scheduler/--workers need it)

        self._cluster = None
        if scheduler:
            try:
                self._client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError) as exc:
                raise UserInputError(f"cannot reach the dask scheduler ({exc})", field="--scheduler", got=scheduler) from None
        else:
            self._cluster = LocalCluster(n_workers=workers or 2, threads_per_worker=1, processes=True,
                                         host="127.0.0.1", dashboard_address=None)
            self._client = Client(self._cluster)

    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        return self._client.submit(fn, *args, pure=False)

    def close(self) -> None:
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()

    def __enter__(self) -> DaskExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

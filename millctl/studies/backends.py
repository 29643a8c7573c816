"""Where a study's points run: in this process, on all local cores, or on a Dask distributed cluster.

Every backend maps :func:`~millctl.studies.engine.evaluate_batch` over batches
of points and yields the batches' rows *in submission order*, so a study's
results are the same point for point whatever runs them.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, Protocol

from millctl.errors import InvalidInputError
from millctl.studies.engine import PointTask, evaluate_batch

Rows = list[dict[str, Any]]


class Backend(Protocol):
    """Runs batches of points and yields their rows in order."""

    name: str
    workers: int

    def map(self, batches: Iterable[Sequence[PointTask]]) -> Iterator[Rows]:
        """Rows of each batch, in the order the batches were given."""
        ...

    def close(self) -> None:
        """Release workers or the cluster connection."""
        ...


def local_cores() -> int:
    """The cores this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


class SerialBackend:
    """Every point in this process (one worker)."""

    name = "serial"
    workers = 1

    def map(self, batches: Iterable[Sequence[PointTask]]) -> Iterator[Rows]:
        """Evaluate batch after batch."""
        for batch in batches:
            yield evaluate_batch(batch)

    def close(self) -> None:
        """Nothing to release."""


class LocalBackend:
    """A pool of worker processes on this machine (forkserver: clean workers, no inherited threads)."""

    name = "local"

    def __init__(self, workers: int) -> None:
        if workers < 1:
            raise InvalidInputError(f"workers = {workers} must be ≥ 1")
        self.workers = workers
        context = multiprocessing.get_context("forkserver")
        self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=context)

    def map(self, batches: Iterable[Sequence[PointTask]]) -> Iterator[Rows]:
        """Submit every batch; yield their rows in order as they finish."""
        yield from self._pool.map(evaluate_batch, batches)

    def close(self) -> None:
        """Shut the pool down (cancelling batches not started)."""
        self._pool.shutdown(wait=True, cancel_futures=True)


class DaskBackend:
    """An existing Dask distributed cluster (``--scheduler ADDRESS``), or a given ``distributed.Client``."""

    name = "dask"

    def __init__(self, address: str | None = None, client: Any = None) -> None:
        try:
            from distributed import Client
        except ImportError:
            raise InvalidInputError(
                "--scheduler needs Dask distributed: pip install 'millctl[dask]' (docs/studies.md#scale)"
            ) from None
        self._own = client is None
        if client is None:
            try:
                client = Client(address, timeout="10s")
            except OSError as exc:
                raise InvalidInputError(f"cannot reach the Dask scheduler at {address}: {exc}") from None
        self._client = client
        self.workers = max(sum(client.nthreads().values()), 1)

    def map(self, batches: Iterable[Sequence[PointTask]]) -> Iterator[Rows]:
        """Submit every batch as a task; gather the rows in submission order."""
        futures = [self._client.submit(evaluate_batch, list(b), pure=False) for b in batches]
        try:
            for future in futures:
                yield future.result()
        finally:
            for future in futures:
                future.cancel()

    def close(self) -> None:
        """Close the client if this backend opened it."""
        if self._own:
            self._client.close()


def make_backend(workers: int | None = None, scheduler: str | None = None) -> Backend:
    """The backend for the command line: Dask when a scheduler is named, else local processes."""
    if scheduler:
        return DaskBackend(scheduler)
    count = local_cores() if workers is None else workers
    return SerialBackend() if count == 1 else LocalBackend(count)


def batched(tasks: Sequence[PointTask], size: int) -> list[list[PointTask]]:
    """Consecutive batches of at most ``size`` points."""
    return [list(tasks[i : i + size]) for i in range(0, len(tasks), max(size, 1))]


ProgressHook = Callable[[int], None]

__all__ = [
    "Backend",
    "DaskBackend",
    "LocalBackend",
    "ProgressHook",
    "SerialBackend",
    "batched",
    "local_cores",
    "make_backend",
]

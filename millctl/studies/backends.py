"""Where a study's points run: in this process, on all local cores, or on a Dask distributed cluster.

Every backend maps :func:`~millctl.studies.engine.evaluate_batch` over batches
of points and yields each batch's rows as soon as it is finished (in any order:
the runner files rows by point, so a study's results are the same point for
point whatever runs them, and an interruption loses no finished batch).

Interrupts (issue 40): :meth:`Backend.abort` stops at once — local workers are
killed, queued batches and Dask futures cancelled. Local workers ignore SIGINT
(Ctrl+C reaches the whole process group; the parent decides), and never outlive
the study: each asks the kernel for SIGKILL when its parent dies
(``prctl(PR_SET_PDEATHSIG)``, Linux) and watches the study's PID besides (the
forkserver, not the study, is a worker's parent; and other systems have no prctl).
"""

from __future__ import annotations

import ctypes
import math
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any, Protocol

from millctl.errors import InvalidInputError
from millctl.studies.engine import PointTask, evaluate_batch
from millctl.studies.metrics import METRICS, needs_slip_run

Rows = list[dict[str, Any]]


class Backend(Protocol):
    """Runs batches of points and yields their rows in order."""

    name: str
    workers: int

    def map(self, batches: Iterable[Sequence[PointTask]]) -> Iterator[Rows]:
        """Rows of each batch, as each finishes."""
        ...

    def close(self) -> None:
        """Release workers or the cluster connection."""
        ...

    def abort(self) -> None:
        """Stop now: kill the workers, drop what is queued (after Ctrl+C)."""
        ...


PR_SET_PDEATHSIG = 1
"""prctl(2) option: the signal this process gets when its parent dies (Linux)."""
PARENT_WATCH_S = 0.5
"""How often a worker checks that the study is still there (s)."""


def _running(pid: int) -> bool:
    """True while ``pid`` runs (a zombie, exited but not yet reaped by its parent, does not)."""
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, PermissionError):  # gone, or the PID reused by another user's process
        return False
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):  # no /proc (not Linux): kill(pid, 0) is all there is
        return True


def _die_with(study_pid: int) -> None:
    """In a worker: leave Ctrl+C to the study, die with the forkserver (prctl) and with the study (watch)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the watch below is the only guard
        pass

    def watch() -> None:
        while True:
            time.sleep(PARENT_WATCH_S)
            if not _running(study_pid):
                os._exit(1)

    threading.Thread(target=watch, name="millctl-study-watch", daemon=True).start()


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

    def abort(self) -> None:
        """Nothing runs outside this process."""


class LocalBackend:
    """A pool of worker processes on this machine (forkserver: clean workers, no inherited threads)."""

    name = "local"

    def __init__(self, workers: int) -> None:
        if workers < 1:
            raise InvalidInputError(f"workers = {workers} must be ≥ 1")
        self.workers = workers
        context = multiprocessing.get_context("forkserver")
        self._pool = ProcessPoolExecutor(
            max_workers=workers, mp_context=context, initializer=_die_with, initargs=(os.getpid(),)
        )

    def map(self, batches: Iterable[Sequence[PointTask]]) -> Iterator[Rows]:
        """Submit the batches as fewer, larger tasks (:func:`pool_tasks`); yield each batch's rows as its task ends."""
        tasks = pool_tasks([list(b) for b in batches], self.workers)
        pending: set[Future[list[Rows]]] = {self._pool.submit(_evaluate_batches, t) for t in tasks}
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    yield from future.result()
        finally:
            for future in pending:
                future.cancel()

    def worker_pids(self) -> list[int]:
        """The PIDs of the pool's worker processes (started on the first batch)."""
        return [p.pid for p in self._processes() if p.pid is not None]

    def _processes(self) -> list[Any]:
        # the pool's own table of workers (Python 3.14 adds ProcessPoolExecutor.terminate_workers())
        return list((self._pool._processes or {}).values())

    def close(self) -> None:
        """Shut the pool down (cancelling batches not started)."""
        self._pool.shutdown(wait=True, cancel_futures=True)

    def abort(self) -> None:
        """Kill the workers (a running batch is lost; finished ones are saved) and drop the queue."""
        processes = self._processes()
        for process in processes:
            if process.is_alive():
                process.kill()
        self._pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.join(timeout=5.0)


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
        self._futures: list[Any] = []
        self.workers = max(sum(client.nthreads().values()), 1)

    def map(self, batches: Iterable[Sequence[PointTask]]) -> Iterator[Rows]:
        """Submit the batches as fewer, larger tasks (:func:`pool_tasks`); yield each batch's rows as its task ends."""
        from distributed import as_completed

        tasks = pool_tasks([list(b) for b in batches], self.workers)
        futures = [self._client.submit(_evaluate_batches, t, pure=False) for t in tasks]
        self._futures = futures
        try:
            for _future, results in as_completed(futures, with_results=True):
                yield from results
        finally:
            for future in futures:
                future.cancel()

    def close(self) -> None:
        """Close the client if this backend opened it."""
        if self._own:
            self._client.close()

    def abort(self) -> None:
        """Cancel every batch not yet gathered (the cluster's workers are the cluster's)."""
        for future in self._futures:
            future.cancel()
        self.close()


POINT_S = {"a": 5e-5, "b_sample": 6e-6, "s_phase": 5e-2, "c_point": 3e-4, "c_revolution": 1.05e-3,
           "c_slip_revolution": 2e-3}  # fmt: skip
"""Nominal serial cost of a point through the runner (s, wall, warm) by level: level (a) whole; level (b)
per cam-phase sample; level (s) per slip-ridden phase; level (c) a point plus one per simulated
revolution, and its second run with the slip ride one more per revolution. From one serial run of
bench/study.py's studies (level (c) 1.4 ms a point at one revolution, 4.5 ms at four; level (s) 0.45 s a
point at 8 phases; level (b) integrated 2.2e-4 s a point at 37 samples) and bench/level_c.py (with slip
0.14 s for 20 scenes of four revolutions: the rods slide, ~430 slide steps an event)."""
INTEGRATED_SAMPLES = 28
"""Level (b) integrated over the cam phase: the samples a point takes on the benchmark's 100 × 100 map
(bench/study.py, "Where the integrated map's time goes": 25.3 a point with the adaptive rule of
:mod:`millctl.studies.phase_integral`, against 37.2 with the doubling it replaced), rounded up."""
WORKER_STARTUP_S = 3.0
"""Nominal start-up of a local pool, its workers' imports and compiled code loaded (s; bench/study.py measures it)."""


def point_cost_s(
    levels: Iterable[str],
    revolutions: float = 4.0,
    cam_phases: int | None = None,
    slip_phases: int = 8,
    slip_run: bool = False,
) -> float:
    """c: the nominal serial cost of one point (s) of a study with metrics of ``levels`` ("a", "b", "s", "c").

    Level (b) costs its K samples (``cam_phases``; None: integrated, :data:`INTEGRATED_SAMPLES`), level (s)
    its ``slip_phases`` rides and level (c) its ``revolutions`` of simulated time, twice with ``slip_run`` (the
    ``slip_sim_*`` metrics, :func:`~millctl.studies.metrics.needs_slip_run`), at :data:`POINT_S`.
    """
    wanted = set(levels)
    cost = POINT_S["a"]
    if "b" in wanted:
        cost += POINT_S["b_sample"] * (INTEGRATED_SAMPLES if cam_phases is None else cam_phases)
    if "s" in wanted:
        cost += POINT_S["s_phase"] * slip_phases
    if "c" in wanted:
        cost += POINT_S["c_point"] + POINT_S["c_revolution"] * revolutions
        if slip_run:
            cost += POINT_S["c_slip_revolution"] * revolutions
    return cost


POOL_TASK_S = 0.25
"""The least nominal serial work of one task sent to workers (s, :func:`point_cost_s`). A task costs the study's
process the same whatever its size: on a 2-worker local Dask cluster, where the scheduler and the client share
the workers' cores, ~3 ms of CPU (0.52 s for 100 tasks of 16 level-(c) points, 0.20 s for 4 of 400); beside a
task of 16 level-(c) points (~20 ms of work) that is ~15 % more CPU, beside one of 0.25 s ~1 %. The local
pool's pickling and result threads cost less a task, but it gains too (docs/studies.md#scale-and-resume)."""
POOL_TASKS_PER_WORKER = 4
"""Tasks are never merged below this many a worker, so that the last ones still balance the workers."""


def pool_tasks(
    batches: Sequence[list[PointTask]], workers: int, least_s: float = POOL_TASK_S
) -> list[list[list[PointTask]]]:
    """Consecutive batches merged into tasks of ≥ ``least_s`` nominal work, ≥ 4 tasks a worker where possible.

    Each task is a list of the runner's batches (its unit of saving and progress, kept); a task costs the
    study's process (and Dask's scheduler) the same whatever its size, so fewer, larger ones leave the cores
    to the points. Both pools (:class:`LocalBackend`, :class:`DaskBackend`) send these.
    """
    if not batches:
        return []
    first = batches[0][0]
    levels = {METRICS[n].level for n in first.metrics}
    s = first.settings
    point_s = point_cost_s(levels, s.revolutions, s.cam_phases or None, s.slip_phases, needs_slip_run(first.metrics))
    points = sum(len(b) for b in batches)
    mean_batch_s = point_s * points / len(batches)
    per_task = max(1, math.ceil(least_s / mean_batch_s))
    per_task = min(per_task, max(1, len(batches) // (POOL_TASKS_PER_WORKER * max(workers, 1))))
    return [list(batches[i : i + per_task]) for i in range(0, len(batches), per_task)]


def _evaluate_batches(batches: Sequence[Sequence[PointTask]]) -> list[Rows]:
    """One task of a pool: the rows of each of its batches (:func:`~millctl.studies.engine.evaluate_batch`)."""
    return [evaluate_batch(b) for b in batches]


def worth_workers(points: int, point_s: float, workers: int, startup_s: float = WORKER_STARTUP_S) -> bool:
    """Whether ``workers`` workers keep ≥ 80 % efficiency on ``points`` points of cost ``point_s``: N·c ≥ 4·w·S.

    With N points of serial cost c (:func:`point_cost_s`) and a pool that takes S to start, the efficiency
    is N c / (w S + N c), ≥ 0.8 exactly when N c ≥ 4 w S — the rule bench/study.py prints and sizes its
    parallel studies by: a level-(c) study pays from a few thousand points, a level-(a, b) one only past
    ~10⁵ (docs/studies.md).
    """
    return workers > 1 and points * point_s >= 4.0 * workers * startup_s


def make_backend(
    workers: int | None = None,
    scheduler: str | None = None,
    points: int | None = None,
    point_s: float = POINT_S["c_point"] + POINT_S["c_revolution"],
) -> Backend:
    """The backend for the command line: Dask when a scheduler is named, else local processes.

    Without ``workers``: every local core when the study (``points`` of serial cost ``point_s``,
    :func:`point_cost_s`) is large enough to gain from them (:func:`worth_workers`), else this process alone.
    """
    if scheduler:
        return DaskBackend(scheduler)
    count = local_cores() if workers is None else workers
    if workers is None and points is not None and not worth_workers(points, point_s, count):
        count = 1
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
    "point_cost_s",
    "pool_tasks",
    "worth_workers",
]

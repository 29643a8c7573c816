"""The node's physics summary off the tick, on one worker thread.

One :func:`~millctl.physics.telemetry.revolution_summary` takes 0.2 ms to
~100 ms, more than a 10 ms tick, so the tick only hands speeds over and picks
up finished summaries. (A worker process on a pipe was tried as well: at 100 Hz
on a loaded two-core machine it measured no better than the thread, and took
a second to start, so the thread stays.)
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

from millctl.physics.model import MillModel
from millctl.physics.telemetry import RevolutionSummary, revolution_summary


class ThreadWorker:
    """Summaries on one worker thread."""

    def __init__(self, model: MillModel) -> None:
        self._model = model
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="physics")
        self._future: Future[RevolutionSummary] | None = None

    @property
    def busy(self) -> bool:
        """True while a summary is being computed."""
        return self._future is not None and not self._future.done()

    def submit(self, omega_r_rad_s: float, omega_v_rad_s: float) -> None:
        """Start a summary at these speeds (rad/s)."""
        self._future = self._executor.submit(revolution_summary, self._model, omega_r_rad_s, omega_v_rad_s)

    def poll(self) -> RevolutionSummary | None:
        """The finished summary, once."""
        future = self._future
        if future is None or not future.done():
            return None
        self._future = None
        return future.result()

    def close(self) -> None:
        """Stop the thread (a running summary finishes)."""
        self._executor.shutdown(wait=False, cancel_futures=True)


__all__ = ["ThreadWorker"]

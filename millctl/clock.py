"""Injected clocks: node and controller logic read time only through a :class:`Clock`.

Tests step a :class:`ManualClock` without sleeping, so most tests run far
faster than real time; the processes use :class:`MonotonicClock`.
"""

from __future__ import annotations

import time
from typing import Protocol


class Clock(Protocol):
    """A source of monotonic time in seconds."""

    def now(self) -> float:
        """Current time (s); only differences are meaningful."""
        ...


class MonotonicClock:
    """The real clock: :func:`time.monotonic`."""

    def now(self) -> float:
        """Current monotonic time (s)."""
        return time.monotonic()


class ManualClock:
    """A clock that moves only when told to: for stepping logic in tests."""

    def __init__(self, start_s: float = 0.0) -> None:
        self._now_s = start_s

    def now(self) -> float:
        """Current simulated time (s)."""
        return self._now_s

    def advance(self, dt_s: float) -> float:
        """Move time forward by ``dt_s`` seconds and return the new time."""
        if dt_s < 0.0:
            raise ValueError(f"a clock cannot go backwards (dt_s = {dt_s})")
        self._now_s += dt_s
        return self._now_s


__all__ = ["Clock", "ManualClock", "MonotonicClock"]

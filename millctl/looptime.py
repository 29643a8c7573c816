"""The control loop's lateness, measured every tick (SAFETY 27; docs/safety.md#host-starvation).

A tick is *late* by how long after its scheduled start it began (s): the
loop schedules tick k at ``t0 + k · controller_tick_s`` and measures
``time.monotonic()`` against it as the tick starts. A loop whose host gives it
the CPU on time is late by well under a millisecond; a loaded host without a
real-time policy makes it hundreds of milliseconds late, and once that passes
the node's watchdog bound (``timing.watchdog_timeout_s``) the node stops the
mill for want of a heartbeat. :class:`LoopLateness` keeps the statistics the
service shows and records: the last, the mean, the maximum since the start,
the maximum over a recent window, and when the last tick late past the
warning threshold was.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

WARN_FRACTION = 0.5
"""A tick late by this fraction of the node's watchdog bound is a warning (half the margin is gone)."""
WINDOW_S = 10.0
"""The recent window of :attr:`LoopLateness.recent_max_s` (s)."""
HOST_CAUSES = ("WATCHDOG", "stale")
"""Trip causes a late loop brings about: the node heard no heartbeat in time, or the controller no telemetry."""
REALTIME_DOC = "docs/deployment.md#real-time-priority"


def starvation_message(lateness_s: float, bound_s: float) -> str:
    """The operator's sentence for a trip caused by a late control loop."""
    return (
        f"the control loop ran {lateness_s * 1e3:.0f} ms late; the node's watchdog allows {bound_s * 1e3:.0f} ms: "
        f"the host is overloaded, see {REALTIME_DOC}"
    )


@dataclass(frozen=True)
class LateTick:
    """One tick late past the warning threshold."""

    at_s: float
    """When it started (s, time.monotonic)."""
    lateness_s: float


class LoopLateness:
    """Lateness of each tick of a periodic loop (s), against the warning threshold of a watchdog bound."""

    def __init__(self, bound_s: float, *, warn_fraction: float = WARN_FRACTION, window_s: float = WINDOW_S) -> None:
        if not bound_s > 0.0:
            raise ValueError(f"loop lateness: the watchdog bound {bound_s!r} s must be > 0")
        if not 0.0 < warn_fraction < 1.0:
            raise ValueError(f"loop lateness: the warning fraction {warn_fraction!r} must be in (0, 1)")
        self.bound_s = bound_s
        self.warn_s = warn_fraction * bound_s
        """Lateness from which a tick is a warning (s)."""
        self.window_s = window_s
        self.ticks = 0
        self.late_ticks = 0
        """Ticks late by ``warn_s`` or more."""
        self.last_s = 0.0
        self.max_s = 0.0
        self._total_s = 0.0
        self._recent: deque[tuple[float, float]] = deque()
        """(start, lateness) of the ticks in the window whose lateness is a new maximum from there on."""
        self.last_late: LateTick | None = None
        self._since_take_s = 0.0

    def record(self, at_s: float, lateness_s: float) -> LateTick | None:
        """Count one tick that started at ``at_s`` (s) ``lateness_s`` late; the LateTick when past the threshold."""
        lateness_s = max(lateness_s, 0.0)
        self.ticks += 1
        self.last_s = lateness_s
        self._total_s += lateness_s
        self.max_s = max(self.max_s, lateness_s)
        self._since_take_s = max(self._since_take_s, lateness_s)
        recent = self._recent
        while recent and recent[-1][1] <= lateness_s:  # a monotonic deque: the window's maximum is at its head
            recent.pop()
        recent.append((at_s, lateness_s))
        while recent[0][0] < at_s - self.window_s:
            recent.popleft()
        if lateness_s < self.warn_s:
            return None
        self.late_ticks += 1
        self.last_late = LateTick(at_s, lateness_s)
        return self.last_late

    def take_max(self) -> float:
        """The largest lateness since the last call (s), for a run record's sample."""
        worst_s, self._since_take_s = self._since_take_s, 0.0
        return worst_s

    @property
    def mean_s(self) -> float:
        """Mean lateness since the start (s)."""
        return self._total_s / self.ticks if self.ticks else 0.0

    @property
    def recent_max_s(self) -> float:
        """The largest lateness within the last ``window_s`` of ticks (s)."""
        return self._recent[0][1] if self._recent else 0.0

    def late_within(self, now_s: float, within_s: float) -> LateTick | None:
        """The last tick late past the threshold if it started within ``within_s`` before ``now_s``."""
        late = self.last_late
        return late if late is not None and now_s - late.at_s <= within_s else None

    def as_dict(self) -> dict[str, float | int]:
        """The figures, in ms, JSON-ready."""
        return {
            "last_ms": round(self.last_s * 1e3, 2),
            "mean_ms": round(self.mean_s * 1e3, 3),
            "max_ms": round(self.max_s * 1e3, 2),
            "recent_max_ms": round(self.recent_max_s * 1e3, 2),
            "warn_ms": round(self.warn_s * 1e3, 1),
            "bound_ms": round(self.bound_s * 1e3, 1),
            "ticks": self.ticks,
            "late_ticks": self.late_ticks,
        }


__all__ = ["HOST_CAUSES", "REALTIME_DOC", "WARN_FRACTION", "WINDOW_S", "LateTick", "LoopLateness",
           "starvation_message"]

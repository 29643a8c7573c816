"""Know the host (SAFETY 27): the control loop's lateness, its warnings, and trips the host caused.

The service's loop hands every tick's lateness to :class:`HostWatch`
(:mod:`millctl.looptime` keeps the figures). A tick late by half the
node's watchdog bound or more is a warning: in the log, and as a ``host``
event (at most one per :data:`WARN_EVERY_S`, counting the late ticks in
between), which the TUI shows as a notification. A trip whose cause is the
host's, not the mill's (the node's WATCHDOG fault, stale telemetry) within
:meth:`HostWatch.trip_window_s` of a late tick is named as host starvation
with the figures, in a ``host`` event and in the service's warnings: "the
control loop ran 612 ms late; the node's watchdog allows 250 ms: the host is
overloaded, see docs/deployment.md#real-time-priority". Each tick also feeds
systemd's watchdog (:mod:`millctl.service.sdnotify`), so a hung loop is
restarted. :func:`realtime_policy_problem` says when the service runs
without a real-time scheduling policy.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from typing import Any

from millctl.api import EventKind
from millctl.config.models import MillConfig
from millctl.controller import Controller, ControllerState
from millctl.looptime import HOST_CAUSES, REALTIME_DOC, LoopLateness, starvation_message
from millctl.service.sdnotify import Notifier

log = logging.getLogger(__name__)

WARN_EVERY_S = 5.0
"""At most one late-loop warning event in this long (s); the late ticks in between are counted in the next."""
Record = Callable[..., Any]
"""``journal.add(kind, source, message, **data)``."""


def realtime_policy_problem() -> str | None:
    """Why this process has no real-time scheduling policy (None when it has SCHED_FIFO or SCHED_RR)."""
    try:
        policy = os.sched_getscheduler(0)
    except (AttributeError, OSError) as exc:
        return f"the scheduling policy cannot be read ({exc}); {REALTIME_DOC}"
    if policy in (os.SCHED_FIFO, os.SCHED_RR):
        return None
    names = {getattr(os, name): name for name in ("SCHED_OTHER", "SCHED_BATCH", "SCHED_IDLE") if hasattr(os, name)}
    return (
        f"the service runs at scheduling policy {names.get(policy, str(policy))}, not a real-time one: a busy host "
        f"can make the control loop late past the node's watchdog and trip the mill for nothing; see {REALTIME_DOC}"
    )


class HostWatch:
    """The loop's lateness, its warnings, host-starvation trips, and systemd's watchdog (times: time.monotonic)."""

    def __init__(self, config: MillConfig, record: Record, notifier: Notifier | None = None) -> None:
        timing = config.timing
        self.lateness = LoopLateness(timing.watchdog_timeout_s)
        self.record = record
        self.notifier = notifier if notifier is not None else Notifier()
        self.trip_window_s = 2.0 * (config.interlock.min_stale_s + timing.watchdog_timeout_s)
        """How long after a late tick a host-caused trip is laid at the host's door (s)."""
        self.starvation: str | None = None
        """The last trip named as host starvation (None when none since the last reset)."""
        self._next_warn_s = float("-inf")
        self._unwarned = 0
        self._tripped = False

    def tick(self, at_s: float, lateness_s: float, controller: Controller) -> None:
        """One tick that started at ``at_s``, ``lateness_s`` late (s); run after the tick, in the loop thread."""
        late = self.lateness.record(at_s, lateness_s)
        if late is not None:
            self._unwarned += 1
            if at_s >= self._next_warn_s:
                self._warn(late.lateness_s)
                self._next_warn_s = at_s + WARN_EVERY_S
        self._judge_trip(at_s, controller)
        self.notifier.ping(at_s)

    def _warn(self, lateness_s: float) -> None:
        figures = self.lateness
        message = (
            f"the control loop ran {lateness_s * 1e3:.0f} ms late ({self._unwarned} late tick"
            f"{'' if self._unwarned == 1 else 's'} since the last warning; warning from {figures.warn_s * 1e3:.0f} "
            f"ms, the node's watchdog allows {figures.bound_s * 1e3:.0f} ms): the host is busy, see {REALTIME_DOC}"
        )
        log.warning("%s", message)
        self.record(EventKind.HOST, "service", message, **{**figures.as_dict(), "late_ticks": self._unwarned})
        self._unwarned = 0

    def _judge_trip(self, now_s: float, controller: Controller) -> None:
        tripped = controller.state is ControllerState.TRIPPED
        if tripped and not self._tripped:
            cause = controller.trip_cause
            late = self.lateness.late_within(now_s, self.trip_window_s)
            if late is not None and any(word in cause for word in HOST_CAUSES):
                worst_s = max(late.lateness_s, self.lateness.recent_max_s)
                named = starvation_message(worst_s, self.lateness.bound_s)
                self.starvation = f"trip caused by host starvation: {named}"
                log.error("%s (trip cause: %s)", self.starvation, cause)
                self.record(EventKind.HOST, "service", self.starvation, trip_cause=cause, host_starvation=True,
                            lateness_ms=round(worst_s * 1e3, 1), bound_ms=round(self.lateness.bound_s * 1e3, 1))
        if not tripped and self._tripped:
            self.starvation = None
        self._tripped = tripped

    def sample(self) -> dict[str, float]:
        """What a run record's sample carries of the host: the worst lateness since the last sample (ms)."""
        return {"loop_lateness_ms": round(self.lateness.take_max() * 1e3, 2),
                "watchdog_bound_ms": round(self.lateness.bound_s * 1e3, 1)}

    def summary(self) -> str:
        """The session's loop lateness in one sentence (recorded as the service stops)."""
        f = self.lateness
        return (
            f"control loop lateness over {f.ticks} ticks: mean {f.mean_s * 1e3:.2f} ms, max {f.max_s * 1e3:.0f} ms; "
            f"{f.late_ticks} tick{'' if f.late_ticks == 1 else 's'} late by {f.warn_s * 1e3:.0f} ms or more "
            f"(the node's watchdog allows {f.bound_s * 1e3:.0f} ms)"
        )

    def as_dict(self) -> dict[str, Any]:
        """The loop's lateness figures (ms) and the last host-starvation trip, JSON-ready."""
        return {**self.lateness.as_dict(), "starvation": self.starvation}


__all__ = ["HOST_CAUSES", "REALTIME_DOC", "WARN_EVERY_S", "HostWatch", "realtime_policy_problem",
           "starvation_message"]

"""A bluesky suspender for the mill: pause a plan while the mill is TRIPPED or its control lease is lost.

Watches :attr:`Mill.readiness <millctl.bluesky.devices.Mill.readiness>` (see
:class:`~millctl.bluesky.link.Readiness`). It trips on ``TRIPPED`` and on ``LEASE_LOST``; the RunEngine then
stops what it moved (the mill's ``stop()``: nothing to do on a tripped mill), rewinds to the last checkpoint and
waits. While tripped, the device gives control back, so the operator can reset and arm (TUI or
``millctl reset; millctl arm``). The plan resumes once the mill is ``READY`` again: ARMED or RUNNING with the
lease taken back by the device, which it does as soon as the operator has released control on an armed mill.
``DISABLED`` (reset, not armed yet) neither suspends nor resumes.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Mapping
from typing import Any

from bluesky.run_engine import in_bluesky_event_loop
from bluesky.suspenders import SuspenderBase

from millctl.bluesky.devices import Mill
from millctl.bluesky.link import Readiness, S

SUSPEND_ON = frozenset({Readiness.TRIPPED, Readiness.LEASE_LOST})


def reading_value(reading: Mapping[str, Any] | str) -> str:
    """The value of an ophyd-async reading ``{name: {"value": …}}`` (or a bare value), as a string."""
    if isinstance(reading, Mapping):
        (only,) = reading.values()
        return str(only["value"])
    return str(reading)


def _in_loop(RE: Any, action: Callable[[], None]) -> None:
    """Run ``action`` in the RunEngine's event loop (ophyd-async subscribes only there), and wait for it."""
    if in_bluesky_event_loop():
        action()
        return

    async def run() -> None:
        action()

    asyncio.run_coroutine_threadsafe(run(), RE.loop).result()


class SuspendWhenMillNotReady(SuspenderBase):
    """Suspend while the mill is TRIPPED or the plan's lease is lost; resume when it is READY again."""

    def __init__(self, mill: Mill, *, sleep: float = 0.0, pre_plan: Any = None, post_plan: Any = None) -> None:
        super().__init__(mill.readiness, sleep=sleep, pre_plan=pre_plan, post_plan=post_plan,  # type: ignore[no-untyped-call]
                         tripped_message="the mill is tripped or its control lease is lost: reset and arm it "
                         "(docs/bluesky.md#suspending)")
        self._mill = mill

    def install(self, RE: Any, *, event_type: Any = None) -> None:
        """Watch the readiness signal (an ophyd-async signal: readings go to ``__call__``)."""
        with self._lock:
            self.RE = RE
        _in_loop(RE, lambda: self._sig.subscribe_reading(self))
        self._mill.suspenders += 1

    def remove(self) -> None:
        """Stop watching; the mill's moves fail on a trip again once no suspender watches."""
        if self.RE is not None:
            self._mill.suspenders -= 1
        super().remove()  # type: ignore[no-untyped-call]

    def _should_suspend(self, value: Mapping[str, Any] | str) -> bool:
        return reading_value(value) in SUSPEND_ON

    def _should_resume(self, value: Mapping[str, Any] | str) -> bool:
        return reading_value(value) == Readiness.READY

    def _get_justification(self) -> str:
        if not self.tripped:
            return ""
        link = self._mill.link
        status = None if link is None else link.status
        why = "" if status is None else f"{status.state} {status.trip_cause}".strip()
        lost = "" if link is None or not link.lost_reason or status is None or status.state is S.TRIPPED \
            else f"; lease: {link.lost_reason}"
        return f"mill {self._mill.name}: {why}{lost} — {self._tripped_message}"


__all__ = ["SUSPEND_ON", "SuspendWhenMillNotReady", "reading_value"]

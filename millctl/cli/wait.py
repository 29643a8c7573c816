"""``--wait``: after an accepted command, follow the status until what it asked for is reached, or exit 2.

The service answers a command when it has accepted it; the drives then ramp,
and a reset completes once the node confirms. ``--wait`` polls the status
until the command's goal holds (:data:`GOALS`): arm → ARMED, disarm →
DISABLED, stop → standstill out of STOPPING, set → both drives at their
targets with the ramp done, reset → out of TRIPPED. A trip on the way, or the
timeout, ends the wait with :class:`NotReached` (exit 2, as an aborted run).
Progress goes to stderr every :data:`PROGRESS_EVERY_S`, so no wait is silent.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from millctl.api import ControllerState
from millctl.errors import InterlockError

if TYPE_CHECKING:
    from millctl.api import StatusOut
    from millctl.client import Client

REACHED_RPM = 3.0
"""A measured speed this close to its target has reached it (rpm): the interlock's measurement tolerance."""
POLL_S = 0.2
"""How often the status is asked for while waiting (s)."""
PROGRESS_EVERY_S = 2.0
"""How often a wait says what it is waiting for (s)."""
DEFAULT_TIMEOUT_S = {"arm": 10.0, "disarm": 10.0, "stop": 120.0, "reset": 15.0, "set": 30.0}
"""``--wait`` without a number: how long each command may take (s); ``set`` adds its ramp's duration."""


class NotReached(InterlockError):
    """The command was accepted but its goal was not reached in time, or a trip ended it (exit 2)."""


def _speeds(s: StatusOut) -> str:
    def rpm(value: float | None) -> str:
        return "—" if value is None else f"{value:.1f}"

    return f"measured ω_r {rpm(s.measured_rotary_rpm)} rpm, ω_v {rpm(s.measured_vibration_rpm)} rpm"


def _standstill(s: StatusOut) -> bool:
    """The controller ended its stop (ARMED or DISABLED) and both drives measure zero within the tolerance."""
    speeds = (s.measured_rotary_rpm, s.measured_vibration_rpm)
    stopped = s.state in (ControllerState.ARMED, ControllerState.DISABLED)
    return stopped and all(v is not None and abs(v) <= REACHED_RPM for v in speeds)


def _at_targets(s: StatusOut) -> bool:
    pairs = ((s.measured_rotary_rpm, s.target_rotary_rpm), (s.measured_vibration_rpm, s.target_vibration_rpm))
    ramp_done = not s.ramp_remaining_s
    return ramp_done and all(m is not None and t is not None and abs(m - t) <= REACHED_RPM for m, t in pairs)


GOALS: dict[str, tuple[str, Callable[[StatusOut], bool]]] = {
    "arm": ("state ARMED", lambda s: s.state is ControllerState.ARMED),
    "disarm": ("state DISABLED", lambda s: s.state is ControllerState.DISABLED),
    "stop": ("standstill", _standstill),
    "set": ("both drives at their targets", lambda s: s.state is ControllerState.RUNNING and _at_targets(s)),
    "reset": ("the trip cleared", lambda s: s.state is not ControllerState.TRIPPED),
}
"""Per command: what ``--wait`` waits for, in words and as a test of the status."""


def wait_for_goal(client: Client, command: str, timeout_s: float, say: Callable[[str], None]) -> StatusOut:
    """Poll the status until ``command``'s goal holds; return that status, or raise :class:`NotReached`."""
    words, reached = GOALS[command]
    start = time.monotonic()
    said = start
    while True:
        status = client.status()
        if reached(status):
            return status
        now = time.monotonic()
        if status.state is ControllerState.TRIPPED and command != "reset":
            raise NotReached(f"{command}: tripped while waiting for {words} ({status.trip_cause or 'no cause'}; "
                             f"{_speeds(status)}): see `millctl status`, docs/safety.md")
        if now - start >= timeout_s:
            raise NotReached(f"{command}: {words} not reached within {timeout_s:g} s (--wait): state "
                             f"{status.state}, {_speeds(status)}")
        if now - said >= PROGRESS_EVERY_S:
            said = now
            say(f"waiting for {words}: {now - start:.0f} s of {timeout_s:g} s, state {status.state}, "
                f"{_speeds(status)}")
        time.sleep(POLL_S)


__all__ = ["DEFAULT_TIMEOUT_S", "GOALS", "NotReached", "wait_for_goal"]

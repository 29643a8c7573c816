"""Link safety of the node: E2E checks on the controller's frames and the heartbeat watchdog.

Every E2E-protected frame from the controller (Command, Heartbeat,
Setpoints) goes through one :class:`~millctl.protocol.E2EReceiver` per
message (SAFETY.md item 3). Only a heartbeat whose status is fresh (OK or
OK_SOME_LOST) feeds the watchdog: a repeated, out-of-sequence or bad-CRC
heartbeat never does (item 2). A net error score at the configured limit on
any of them faults the link.
"""

from __future__ import annotations

import logging

from millctl.config.models import MillConfig
from millctl.protocol import Command, Decoded, E2EReceiver, E2EStatus, Heartbeat, MillMessage, Setpoints

log = logging.getLogger(__name__)

GUARDED: tuple[type[MillMessage], ...] = (Command, Heartbeat, Setpoints)
"""The controller's E2E-protected messages the node checks."""


class LinkMonitor:
    """E2E receivers for the controller's frames and the heartbeat watchdog (times in s)."""

    def __init__(self, config: MillConfig) -> None:
        interlock = config.interlock
        self.timeout_s = config.timing.watchdog_timeout_s
        self.receivers: dict[type[MillMessage], E2EReceiver] = {
            kind: E2EReceiver(
                error_limit=interlock.e2e_error_limit,
                name=kind.__name__,
                sequence_decay_frames=interlock.e2e_sequence_decay_frames,
            )
            for kind in GUARDED
        }
        self.last_heartbeat_s: float | None = None
        """When the last fresh heartbeat arrived (s, node clock); None before the first."""
        self.fresh_heartbeats = 0

    def check(self, decoded: Decoded, now_s: float) -> E2EStatus:
        """Classify one decoded controller frame; a fresh heartbeat feeds the watchdog."""
        receiver = self.receivers[decoded.kind]
        status = receiver.check(decoded)
        if not status.fresh:
            log.debug(
                "%s frame %s (counter %s, E2E score %d, sequence score %d)",
                decoded.kind.__name__,
                status.value,
                decoded.counter,
                receiver.score,
                receiver.sequence_score,
            )
        elif decoded.kind is Heartbeat:
            self.last_heartbeat_s = now_s
            self.fresh_heartbeats += 1
        return status

    def heartbeat_live(self, now_s: float) -> bool:
        """True when a fresh heartbeat arrived within the watchdog timeout."""
        return self.last_heartbeat_s is not None and now_s - self.last_heartbeat_s <= self.timeout_s

    @property
    def faulted(self) -> bool:
        """True while any guarded message's net E2E error score is at or above the limit."""
        return any(receiver.faulted for receiver in self.receivers.values())

    def reset_scores(self) -> None:
        """Clear the error scores (after an accepted RESET); counters resynchronise on the next frame."""
        for receiver in self.receivers.values():
            receiver.clear_scores()


__all__ = ["GUARDED", "LinkMonitor"]

"""Link safety of the node: E2E checks on the controller's frames and the heartbeat watchdog.

Every E2E-protected frame from the controller (Command, Heartbeat,
Setpoints) goes through one :class:`~millctl.protocol.E2EReceiver` per
message (SAFETY.md item 3). Either E2E score at the configured limit on any
of them faults the link. The sequence score is forgiven no faster than the
controller sends (:data:`SENDER_PERIOD`), so a forger that out-sends it
cannot pay back the errors its interleaving makes (item 17).

Only a *fresh* heartbeat feeds the watchdog (items 2 and 16): its E2E status
is fresh (OK or OK_SOME_LOST: never a repeated, out-of-sequence or bad-CRC
one) **and** its ``challenge_echo`` is a challenge this node issued within
``timing.challenge_lifetime_s`` and no older than the challenge the last
fresh heartbeat echoed. Every NodeStatus carries a new 16-bit challenge
(:meth:`LinkMonitor.issue_challenge`); the controller echoes the latest one
it received. The challenges run through all 65 536 values before any
repeats (:class:`ChallengeSequence`), so an old echo can never match a
newer challenge by chance. A 4-bit counter cannot tell a replay, the challenge
can: a recorded heartbeat echoes a challenge that has since been superseded
or has expired, so a recorded sequence replayed after the controller died
feeds nothing, and the watchdog stops the mill (docs/protocol.md, "Heartbeat
freshness").

A faulted link's cause is gone once no guarded frame has been in error for
:meth:`LinkMonitor.quiet_s` (SAFETY 25): the time its genuine sender takes to
send ``e2e_error_limit`` frames, which would have paid the score back had the
sender been sending. The scores themselves heal only on good frames, and in
FAULT the controller sends no Setpoints: waiting for the score alone left a
short bad-CRC burst latched until the node was restarted (issue 37 item 1).
"""

from __future__ import annotations

import logging
import secrets
from collections import deque
from collections.abc import Callable

from millctl.config.models import MillConfig
from millctl.protocol import (
    Command,
    Decoded,
    E2EReceiver,
    E2EStatus,
    Heartbeat,
    MillMessage,
    Setpoints,
    sequence_decay_s,
)

log = logging.getLogger(__name__)

CHALLENGE_VALUES = 1 << 16
"""The heartbeat challenge is a 16-bit field (DBC signal ``NodeStatus.challenge``)."""


class ChallengeSequence:
    """The node's challenges: ``(start + k · step) mod 2¹⁶`` for the k-th NodeStatus, start and odd step drawn at boot.

    An odd step is a generator of the integers mod 2¹⁶, so no value recurs within
    65 536 challenges (54 min at 20 Hz): a heartbeat recorded earlier echoes a value
    that no challenge issued since can equal. Drawing each challenge at random
    instead lets a replayed echo equal a newer live challenge by chance, with
    probability (live challenges)/65 536 per replayed frame; that is rare at the
    host's 10 live challenges but not under the VM's scaled lifetime, where about
    200 are live and a replay loop fed the watchdog for seconds. Start and step are
    drawn at boot (``secrets``) so that a restarted node does not repeat an old run.
    """

    def __init__(self) -> None:
        self.start = secrets.randbits(16)
        self.step = secrets.randbits(16) | 1

    def value(self, serial: int) -> int:
        """The challenge issued as number ``serial`` (0, 1, …) since boot."""
        return (self.start + serial * self.step) % CHALLENGE_VALUES


GUARDED: tuple[type[MillMessage], ...] = (Command, Heartbeat, Setpoints)
"""The controller's E2E-protected messages the node checks."""

SENDER_PERIOD: dict[type[MillMessage], Callable[[MillConfig], float]] = {
    Command: lambda config: config.interlock.command_repeat_s,
    Heartbeat: lambda config: config.timing.heartbeat_period_s,
    Setpoints: lambda config: config.timing.setpoint_period_s,
}
"""How often the controller sends each guarded message at most (s): Heartbeat and Setpoints every period;
a Command, when given, and again every ``command_repeat_s`` while unconfirmed."""


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
                min_decay_s=sequence_decay_s(interlock.e2e_sequence_decay_frames, SENDER_PERIOD[kind](config)),
            )
            for kind in GUARDED
        }
        self.last_heartbeat_s: float | None = None
        """When the last fresh heartbeat arrived (s, node clock); None before the first."""
        self.fresh_heartbeats = 0
        self.expired_echoes = 0
        """Heartbeats with a fresh counter whose echo was not a live challenge newer than the last one accepted."""
        self.lifetime_s = config.timing.challenge_lifetime_s
        self._challenges: deque[tuple[int, int, float]] = deque()
        """Live challenges, oldest first: (serial number, value, issued at s)."""
        self._sequence = ChallengeSequence()
        self._issued = 0
        self._accepted = -1
        """Serial number of the challenge the last fresh heartbeat echoed (-1 before the first)."""
        self._quiet_s = {kind: interlock.e2e_error_limit * SENDER_PERIOD[kind](config) for kind in GUARDED}
        self._last_error_s: dict[type[MillMessage], float] = {}
        """When each guarded message last arrived in error (s, node clock)."""

    def issue_challenge(self, now_s: float) -> int:
        """The next challenge for the NodeStatus about to be sent; live for ``challenge_lifetime_s``."""
        value = self._sequence.value(self._issued)
        self._challenges.append((self._issued, value, now_s))
        self._issued += 1
        while now_s - self._challenges[0][2] > self.lifetime_s:
            self._challenges.popleft()
        return value

    def echo_fresh(self, echo: int, now_s: float) -> bool:
        """True when ``echo`` is a live challenge no older than the one the last fresh heartbeat echoed.

        Accepting one takes every older challenge out of play, so a recorded
        heartbeat can only ever echo a challenge already superseded.
        """
        for serial, value, issued_s in reversed(self._challenges):
            if serial < self._accepted or now_s - issued_s > self.lifetime_s:
                return False
            if value == echo:
                self._accepted = serial
                return True
        return False

    def check(self, decoded: Decoded, now_s: float) -> E2EStatus:
        """Classify one decoded controller frame; a fresh heartbeat feeds the watchdog."""
        receiver = self.receivers[decoded.kind]
        status = receiver.check(decoded, now_s)
        if status.is_error:
            self._last_error_s[decoded.kind] = now_s
        if not status.fresh:
            log.debug(
                "%s frame %s (counter %s, E2E score %d, sequence score %d)",
                decoded.kind.__name__,
                status.value,
                decoded.counter,
                receiver.score,
                receiver.sequence_score,
            )
        elif isinstance(decoded.message, Heartbeat):
            if self.echo_fresh(decoded.message.challenge_echo, now_s):
                self.last_heartbeat_s = now_s
                self.fresh_heartbeats += 1
            else:
                self.expired_echoes += 1
                log.debug("heartbeat echoes challenge %d, not a live one: not fresh", decoded.message.challenge_echo)
        return status

    def heartbeat_live(self, now_s: float) -> bool:
        """True when a fresh heartbeat (counter and challenge) arrived within the watchdog timeout."""
        return self.last_heartbeat_s is not None and now_s - self.last_heartbeat_s <= self.timeout_s

    @property
    def faulted(self) -> bool:
        """True while any guarded message's net E2E error score is at or above the limit."""
        return any(receiver.faulted for receiver in self.receivers.values())

    def quiet_s(self, kind: type[MillMessage]) -> float:
        """How long ``kind`` must arrive without an error for its faulted score's cause to count as gone (s)."""
        return self._quiet_s[kind]

    def errors_present(self, now_s: float) -> bool:
        """True while a guarded message's score is at its limit and it arrived in error within its quiet time.

        What RESET asks of a faulted link (SAFETY 25): a score healed by good
        frames, or no errors for :meth:`quiet_s`, is a cause gone.
        """
        return any(
            receiver.faulted and now_s - self._last_error_s.get(kind, float("-inf")) < self._quiet_s[kind]
            for kind, receiver in self.receivers.items()
        )

    def reset_scores(self) -> None:
        """Clear the error scores (after an accepted RESET); counters resynchronise on the next frame."""
        for receiver in self.receivers.values():
            receiver.clear_scores()


__all__ = ["CHALLENGE_VALUES", "GUARDED", "SENDER_PERIOD", "ChallengeSequence", "LinkMonitor"]

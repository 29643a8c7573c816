"""Every command confirmed: what the controller sent, until the node's reported state shows it done.

A command is *pending* from its first send until a NodeStatus reports a
state of :data:`millctl.safety.commands.CONFIRMED_BY` (a RESET also needs
the fault bits cleared). While pending it is sent again every
``interlock.command_repeat_s`` with a fresh alive counter, so one frame
dropped — lost, or refused as NOT_FRESH because a forged frame took its
counter — is not the end of it. Once ``interlock.command_confirm_s`` has
passed it has *expired*, and the controller escalates: STOP → E-stop, any
other command → a trip naming it (docs/safety.md#every-command-confirmed).
"""

from __future__ import annotations

from dataclasses import dataclass

from millctl.config.models import Interlock
from millctl.protocol import CommandCode, NodeStatus
from millctl.safety.commands import CONFIRMED_BY


@dataclass
class Pending:
    """One command sent and not yet confirmed (times in s, controller clock)."""

    code: CommandCode
    source: str
    reason: str
    first_sent_s: float
    last_sent_s: float
    deadline_s: float
    sends: int = 1


class Confirmations:
    """The commands awaiting the node's confirmation, their repeats and their deadlines."""

    def __init__(self, interlock: Interlock) -> None:
        self.confirm_s = interlock.command_confirm_s
        self.repeat_s = interlock.command_repeat_s
        self.pending: dict[CommandCode, Pending] = {}
        self.confirmed_s: dict[CommandCode, float] = {}
        """When each command was last confirmed (s)."""

    def sent(self, code: CommandCode, source: str, reason: str, now_s: float) -> None:
        """A command went out; a repeat of one already pending keeps its first deadline."""
        pending = self.pending.get(code)
        if pending is None:
            self.pending[code] = Pending(code, source, reason, now_s, now_s, now_s + self.confirm_s)
        else:
            pending.last_sent_s = now_s
            pending.sends += 1

    def reopen(self, code: CommandCode, source: str, reason: str, first_sent_s: float) -> None:
        """Pending again (if it is not): a report from before the node took it had confirmed it.

        It keeps the deadline of its first send at ``first_sent_s``: a reopened
        command is never given longer than one confirmation bound.
        """
        if code not in self.pending:
            self.pending[code] = Pending(code, source, reason, first_sent_s, first_sent_s,
                                         first_sent_s + self.confirm_s)

    def in_flight(self, now_s: float) -> frozenset[CommandCode]:
        """Commands pending, or confirmed within the last confirmation bound (the node may still be acting)."""
        recent = {code for code, t in self.confirmed_s.items() if now_s - t <= self.confirm_s}
        return frozenset(self.pending) | frozenset(recent)

    def confirm(self, status: NodeStatus, now_s: float) -> list[Pending]:
        """Take the commands this NodeStatus confirms off the pending list; return them."""
        done = [
            p
            for code, p in self.pending.items()
            if status.state in CONFIRMED_BY[code] and (code is not CommandCode.RESET or not status.fault_bits)
        ]
        for p in done:
            del self.pending[p.code]
            self.confirmed_s[p.code] = now_s
        return done

    def due(self, now_s: float) -> list[Pending]:
        """Pending commands whose repeat is due (not yet expired)."""
        return [p for p in self.pending.values() if now_s - p.last_sent_s >= self.repeat_s and now_s < p.deadline_s]

    def expired(self, now_s: float) -> list[Pending]:
        """Take the commands past their deadline off the pending list; return them."""
        gone = [p for p in self.pending.values() if now_s >= p.deadline_s]
        for p in gone:
            del self.pending[p.code]
        return gone


__all__ = ["Confirmations", "Pending"]

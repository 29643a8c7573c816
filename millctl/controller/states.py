"""The controller's state machine: an explicit transition table and a reason for every move.

::

    DISCONNECTED ──node seen──▶ DISABLED ──arm──▶ ARMED ──setpoint──▶ RUNNING
                                   ▲ ▲▲            │  ▲                 │
                                   │ │└──disarm────┘  └──standstill── STOPPING ◀─stop─┘
                                   │ └──── node took a DISARM sent before the STOP ┘
                                   │
                                 reset ◀── TRIPPED ◀── any trip, from any state

A trip latches: only RESET leaves TRIPPED (docs/safety.md#what-trips).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

from millctl.api.enums import ControllerState
from millctl.errors import InterlockError

log = logging.getLogger(__name__)


S = ControllerState

TRANSITIONS: dict[ControllerState, frozenset[ControllerState]] = {
    S.DISCONNECTED: frozenset({S.DISABLED, S.TRIPPED}),
    S.DISABLED: frozenset({S.ARMED, S.TRIPPED, S.DISCONNECTED}),
    S.ARMED: frozenset({S.RUNNING, S.DISABLED, S.STOPPING, S.TRIPPED}),
    S.RUNNING: frozenset({S.STOPPING, S.TRIPPED}),
    S.STOPPING: frozenset({S.ARMED, S.RUNNING, S.DISABLED, S.TRIPPED}),
    S.TRIPPED: frozenset({S.DISABLED}),
}
"""Allowed moves: state → the states it may go to. Nothing else is possible."""


class IllegalTransition(InterlockError):
    """A transition the table does not allow (a bug, or a command in the wrong state)."""


@dataclass(frozen=True)
class Transition:
    """One state change, as logged and recorded."""

    time_s: float
    source: ControllerState
    target: ControllerState
    reason: str


class StateMachine:
    """Holds the current state and moves it only along :data:`TRANSITIONS`."""

    def __init__(self, now: Callable[[], float], listener: Callable[[Transition], None] | None = None) -> None:
        self._now = now
        self._state = S.DISCONNECTED
        self._listener = listener
        self.history: list[Transition] = []

    @property
    def state(self) -> ControllerState:
        """The current state."""
        return self._state

    def can_go(self, target: ControllerState) -> bool:
        """True when the table allows moving to ``target`` now."""
        return target in TRANSITIONS[self._state]

    def go(self, target: ControllerState, reason: str) -> Transition | None:
        """Move to ``target`` for ``reason``; a move to the current state is a no-op."""
        if target is self._state:
            return None
        if not self.can_go(target):
            raise IllegalTransition(
                f"cannot go from {self._state} to {target} ({reason}); allowed from {self._state}: "
                f"{', '.join(sorted(TRANSITIONS[self._state])) or 'none'}"
            )
        transition = Transition(self._now(), self._state, target, reason)
        self._state = target
        self.history.append(transition)
        del self.history[:-256]
        log.info("state %s -> %s: %s", transition.source, transition.target, reason)
        if self._listener is not None:
            self._listener(transition)
        return transition


__all__ = ["TRANSITIONS", "ControllerState", "IllegalTransition", "StateMachine", "Transition"]

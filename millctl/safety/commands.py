"""Which command is allowed in which state, and which node state confirms it: one table for every part.

The controller refuses an operator command outside :data:`CONTROLLER_ALLOWS`,
the TUI greys it out with the same table, and the node accepts a wire
command only in the states of :data:`NODE_ACCEPTS` and moves only along
:data:`NODE_TRANSITIONS` (docs/safety.md#state-machine). The controller
counts a command as done only when the node reports a state of
:data:`CONFIRMED_BY` (docs/safety.md#every-command-confirmed), and judges
every node state change against :func:`node_change_commanded`.
"""

from __future__ import annotations

import enum

from millctl.api.enums import ControllerState
from millctl.protocol.messages import CommandCode, NodeState

S = ControllerState
N = NodeState


class Operation(enum.StrEnum):
    """What an operator, a recipe or the service can ask the controller to do."""

    ARM = "arm"
    DISARM = "disarm"
    SET = "set"
    """New speeds (and, with them, a furnace target)."""
    FURNACE = "furnace"
    STOP = "stop"
    RESET = "reset"
    ESTOP = "estop"


CONTROLLER_ALLOWS: dict[Operation, frozenset[ControllerState]] = {
    Operation.ARM: frozenset({S.DISABLED}),
    Operation.DISARM: frozenset({S.ARMED}),
    Operation.SET: frozenset({S.ARMED, S.RUNNING}),
    Operation.FURNACE: frozenset({S.ARMED, S.RUNNING}),
    Operation.STOP: frozenset({S.ARMED, S.RUNNING, S.STOPPING}),
    Operation.RESET: frozenset({S.TRIPPED}),
    Operation.ESTOP: frozenset(S),
}
"""Controller states in which each operation is allowed; elsewhere it is refused with the state named."""

NODE_ACCEPTS: dict[CommandCode, frozenset[NodeState]] = {
    CommandCode.ARM: frozenset({N.DISABLED}),
    CommandCode.DISARM: frozenset({N.ARMED}),
    CommandCode.STOP: frozenset(N),
    CommandCode.RESET: frozenset({N.FAULT}),
}
"""Node states in which each wire command is accepted (STOP in any: where nothing moves it changes nothing)."""

NODE_SETPOINTS_IN: frozenset[NodeState] = frozenset({N.ARMED, N.RUNNING})
"""Node states in which Setpoints frames are accepted (and re-checked)."""

NODE_TRANSITIONS: dict[NodeState, frozenset[NodeState]] = {
    N.DISABLED: frozenset({N.ARMED, N.FAULT}),
    N.ARMED: frozenset({N.RUNNING, N.STOPPING, N.DISABLED, N.FAULT}),
    N.RUNNING: frozenset({N.ARMED, N.STOPPING, N.FAULT}),
    N.STOPPING: frozenset({N.ARMED, N.FAULT}),
    N.FAULT: frozenset({N.DISABLED}),
}
"""The node's allowed moves: state → the states it may go to. Only RESET leaves FAULT."""

CONFIRMED_BY: dict[CommandCode, frozenset[NodeState]] = {
    CommandCode.ARM: frozenset({N.ARMED, N.RUNNING}),
    CommandCode.DISARM: frozenset({N.DISABLED}),
    CommandCode.STOP: frozenset(N) - {N.RUNNING},
    CommandCode.RESET: frozenset({N.DISABLED}),
}
"""Node states that confirm a command the controller sent (RESET also needs no fault bits)."""

COMMANDED_BY: dict[tuple[NodeState, NodeState], CommandCode] = {
    (N.DISABLED, N.ARMED): CommandCode.ARM,
    (N.ARMED, N.DISABLED): CommandCode.DISARM,
    (N.FAULT, N.DISABLED): CommandCode.RESET,
    (N.ARMED, N.STOPPING): CommandCode.STOP,
    (N.RUNNING, N.STOPPING): CommandCode.STOP,
}
"""The node state changes that only a command causes, with that command."""


def node_change_commanded(
    before: NodeState, after: NodeState, sent: frozenset[CommandCode], moving_commanded: bool
) -> bool:
    """True when the controller asked for the node's change from ``before`` to ``after``.

    ``sent`` holds the commands sent and not yet confirmed (or confirmed by
    this very change); ``moving_commanded`` is True while the controller
    commands a speed other than standstill. The node may always fault, and
    may end a stop or come to rest on its own; ARMED → RUNNING needs a
    commanded speed; every other change needs its command.
    """
    if after is before or after is N.FAULT:
        return True
    if after not in NODE_TRANSITIONS[before]:
        return False
    if (before, after) == (N.ARMED, N.RUNNING):
        return moving_commanded
    if (before, after) in ((N.STOPPING, N.ARMED), (N.RUNNING, N.ARMED)):
        return not moving_commanded or before is N.STOPPING
    return COMMANDED_BY[(before, after)] in sent


__all__ = [
    "COMMANDED_BY",
    "CONFIRMED_BY",
    "CONTROLLER_ALLOWS",
    "NODE_ACCEPTS",
    "NODE_SETPOINTS_IN",
    "NODE_TRANSITIONS",
    "Operation",
    "node_change_commanded",
]

"""Which node state changes the controller believes (millctl.safety.commands.node_change_commanded).

The rules of docs/safety.md#believe-only-what-was-commanded, each over every pair of node states and every
set of commands in flight: the node may always fault or stay; a change outside its own table is never
commanded; a stop may end on its own; coming to rest (RUNNING → ARMED) needs standstill commanded, starting
(ARMED → RUNNING) a speed; every other change needs its own command in flight.
"""

from __future__ import annotations

import itertools

import pytest

from millctl.protocol import CommandCode, NodeState
from millctl.safety.commands import node_change_commanded

N = NodeState
C = CommandCode
BY_COMMAND = {
    (N.DISABLED, N.ARMED): C.ARM,
    (N.ARMED, N.DISABLED): C.DISARM,
    (N.FAULT, N.DISABLED): C.RESET,
    (N.ARMED, N.STOPPING): C.STOP,
    (N.RUNNING, N.STOPPING): C.STOP,
}
"""The changes only a command causes (docs/operations.md, the node's state table)."""
ON_ITS_OWN = {(N.ARMED, N.RUNNING), (N.RUNNING, N.ARMED), (N.STOPPING, N.ARMED)}
"""The changes the node makes by itself, following setpoints or ending a stop."""
ALL_SENT = frozenset(CommandCode)
PAIRS = list(itertools.product(N, N))
IN_FLIGHT = [frozenset(c) for k in range(len(CommandCode) + 1) for c in itertools.combinations(CommandCode, k)]


def believed(before: NodeState, after: NodeState) -> set[tuple[frozenset[CommandCode], bool]]:
    """The (commands in flight, moving commanded) situations in which the change is believed."""
    return {
        (sent, moving)
        for sent in IN_FLIGHT
        for moving in (False, True)
        if node_change_commanded(before, after, sent, moving)
    }


EVERY = {(sent, moving) for sent in IN_FLIGHT for moving in (False, True)}


@pytest.mark.parametrize("before", list(N))
def test_the_node_may_always_fault_or_stay(before: NodeState) -> None:
    assert believed(before, N.FAULT) == EVERY
    assert believed(before, before) == EVERY


OUTSIDE = [(b, a) for b, a in PAIRS if a not in (b, N.FAULT) and (b, a) not in BY_COMMAND.keys() | ON_ITS_OWN]
"""Every change outside the node's table."""


@pytest.mark.parametrize(("before", "after"), OUTSIDE)
def test_a_change_outside_the_nodes_table_is_never_commanded(before: NodeState, after: NodeState) -> None:
    assert believed(before, after) == set()


def test_a_stop_may_end_on_its_own() -> None:
    assert believed(N.STOPPING, N.ARMED) == EVERY


def test_coming_to_rest_needs_standstill_commanded_and_starting_a_speed() -> None:
    assert believed(N.RUNNING, N.ARMED) == {(sent, False) for sent in IN_FLIGHT}
    assert believed(N.ARMED, N.RUNNING) == {(sent, True) for sent in IN_FLIGHT}


@pytest.mark.parametrize(("change", "command"), list(BY_COMMAND.items()))
def test_every_other_change_needs_its_own_command_in_flight(
    change: tuple[NodeState, NodeState], command: CommandCode
) -> None:
    assert believed(*change) == {(sent, moving) for sent, moving in EVERY if command in sent}
    assert not node_change_commanded(*change, ALL_SENT - {command}, True)

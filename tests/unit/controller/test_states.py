"""The controller's state machine follows its transition table only."""

from __future__ import annotations

import pytest

from millctl.clock import ManualClock
from millctl.controller.states import ControllerState, IllegalTransition, StateMachine, Transition

S = ControllerState
Path = tuple[ControllerState, ...]


# The machine is explored through its behaviour (``go`` succeeds or raises), never by reading its
# table, and checked against the properties docs/safety.md#state-machine states.


def machine_after(path: Path) -> StateMachine:
    """A fresh machine (DISCONNECTED) moved along ``path``."""
    sm = StateMachine(ManualClock().now)
    for target in path:
        sm.go(target, "test path")
    return sm


def moves_after(path: Path) -> set[ControllerState]:
    """The states the machine accepts a move to after ``path``."""
    accepted: set[ControllerState] = set()
    for target in S:
        sm = machine_after(path)
        if target is sm.state:
            continue
        try:
            sm.go(target, "probe")
        except IllegalTransition:
            continue
        accepted.add(target)
    return accepted


def shortest_paths(avoid: frozenset[ControllerState] = frozenset()) -> dict[ControllerState, Path]:
    """Every state reachable from DISCONNECTED (not through ``avoid``), with a shortest path to it."""
    paths: dict[ControllerState, Path] = {S.DISCONNECTED: ()}
    frontier: list[Path] = [()]
    while frontier:  # each state enters the frontier once: at most len(S) rounds
        path = frontier.pop(0)
        for target in sorted(moves_after(path) - avoid - set(paths)):
            paths[target] = (*path, target)
            frontier.append(paths[target])
    return paths


def test_every_state_is_reachable_from_disconnected() -> None:
    assert set(shortest_paths()) == set(S)


def test_a_trip_is_possible_from_every_state_but_tripped() -> None:
    for state, path in shortest_paths().items():
        assert (S.TRIPPED in moves_after(path)) == (state is not S.TRIPPED), state


def test_tripped_latches_only_reset_to_disabled_leaves_it() -> None:
    assert moves_after(shortest_paths()[S.TRIPPED]) == {S.DISABLED}


def test_nothing_moves_before_arm() -> None:
    """Without passing ARMED, neither RUNNING nor STOPPING can be reached (safe by default)."""
    assert set(shortest_paths(avoid=frozenset({S.ARMED}))) == {S.DISCONNECTED, S.DISABLED, S.TRIPPED}


def test_the_node_must_be_seen_first() -> None:
    """From DISCONNECTED only "node seen" (DISABLED) or a trip."""
    assert moves_after(()) == {S.DISABLED, S.TRIPPED}


def test_running_stops_only_through_stopping_or_a_trip() -> None:
    """A running mill is never disarmed in one step: it ramps down (STOPPING) or trips."""
    assert moves_after(shortest_paths()[S.RUNNING]) == {S.STOPPING, S.TRIPPED}


def test_illegal_move_names_the_allowed_ones() -> None:
    sm = StateMachine(ManualClock().now)
    with pytest.raises(IllegalTransition, match="cannot go from DISCONNECTED to RUNNING"):
        sm.go(S.RUNNING, "test")


def test_transitions_are_recorded_with_reason_and_time() -> None:
    clock = ManualClock()
    seen: list[Transition] = []
    sm = StateMachine(clock.now, seen.append)
    sm.go(S.DISABLED, "node seen")
    clock.advance(1.5)
    sm.go(S.ARMED, "operator armed")
    assert [(t.target, t.reason, t.time_s) for t in seen] == [
        (S.DISABLED, "node seen", 0.0),
        (S.ARMED, "operator armed", 1.5),
    ]
    assert sm.go(S.ARMED, "again") is None


def test_an_illegal_move_lists_every_move_allowed_from_there() -> None:
    sm = machine_after((S.DISABLED,))
    with pytest.raises(
        IllegalTransition, match=r"\(operator stop\); allowed from DISABLED: ARMED, DISCONNECTED, TRIPPED$"
    ):
        sm.go(S.STOPPING, "operator stop")
    assert sm.state is S.DISABLED


def test_the_history_records_each_move_from_where_to_where_and_keeps_the_latest_256() -> None:
    clock = ManualClock()
    seen: list[Transition] = []
    sm = StateMachine(clock.now, seen.append)
    sm.go(S.DISABLED, "node seen")
    for i in range(150):  # 300 moves: ARMED and back
        clock.advance(1.0)
        sm.go(S.ARMED, f"arm {i}")
        sm.go(S.DISABLED, f"disarm {i}")
    assert len(seen) == 301
    assert sm.history == seen[-256:]
    assert (sm.history[-1].source, sm.history[-1].target, sm.history[-1].reason) == (S.ARMED, S.DISABLED, "disarm 149")
    assert (seen[0].source, seen[0].target) == (S.DISCONNECTED, S.DISABLED)

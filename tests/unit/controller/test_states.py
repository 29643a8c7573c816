"""The controller's state machine follows its transition table only."""

from __future__ import annotations

import pytest

from millctl.clock import ManualClock
from millctl.controller.states import TRANSITIONS, ControllerState, IllegalTransition, StateMachine

S = ControllerState


def test_every_state_can_trip_except_tripped():
    for state, targets in TRANSITIONS.items():
        assert (S.TRIPPED in targets) == (state is not S.TRIPPED)


def test_tripped_leaves_only_by_reset_to_disabled():
    assert TRANSITIONS[S.TRIPPED] == frozenset({S.DISABLED})


def test_illegal_move_names_the_allowed_ones():
    sm = StateMachine(ManualClock().now)
    with pytest.raises(IllegalTransition, match="cannot go from DISCONNECTED to RUNNING"):
        sm.go(S.RUNNING, "test")


def test_transitions_are_recorded_with_reason_and_time():
    clock = ManualClock()
    seen = []
    sm = StateMachine(clock.now, seen.append)
    sm.go(S.DISABLED, "node seen")
    clock.advance(1.5)
    sm.go(S.ARMED, "operator armed")
    assert [(t.target, t.reason, t.time_s) for t in seen] == [
        (S.DISABLED, "node seen", 0.0),
        (S.ARMED, "operator armed", 1.5),
    ]
    assert sm.go(S.ARMED, "again") is None

"""What a NodeStatus makes the controller do, and how it is recorded (SAFETY requirement 9).

Every state change the node's report causes is kept in the controller's history with the node's report as
its reason, and every trip a report causes names the node as its source and says what the node reported:
the operator reads why the mill stopped from the record, not from the code.
"""

from __future__ import annotations

from millctl.controller import ControllerState, Event, EventKind
from millctl.protocol import EStop, FaultCode, FaultFlag, NodeState, NodeStatus
from tests.unit.controller.bench import ScriptedNode

S = ControllerState


def trips(bench: ScriptedNode) -> list[Event]:
    return [e for e in bench.events if e.kind is EventKind.TRIP]


def test_each_state_the_node_reports_moves_the_controller_and_is_recorded_as_the_reason(bench: ScriptedNode) -> None:
    bench.armed()
    bench.controller.set_speeds(20.0, 100.0)
    bench.run(1.0, follow=True)
    bench.controller.stop()
    bench.run(0.1, state=NodeState.STOPPING)
    bench.run(0.2, state=NodeState.ARMED)
    bench.controller.disarm()
    bench.run(0.2, state=NodeState.DISABLED)
    assert [(t.source, t.target, t.reason) for t in bench.controller.machine.history] == [
        (S.DISCONNECTED, S.DISABLED, "node seen, DISABLED"),
        (S.DISABLED, S.ARMED, "node ARMED"),
        (S.ARMED, S.RUNNING, "node RUNNING"),
        (S.RUNNING, S.STOPPING, "operator: operator request"),
        (S.STOPPING, S.ARMED, "controlled stop complete"),
        (S.ARMED, S.DISABLED, "node DISABLED (disarmed)"),
    ]
    assert trips(bench) == []


def test_a_node_fault_trips_naming_the_fault_and_every_bit_recorded_as_the_nodes(bench: ScriptedNode) -> None:
    bench.armed()
    bits = FaultFlag.OVERTEMP | FaultFlag.STALL
    bench.say(NodeStatus(NodeState.FAULT, bits, FaultCode.OVERTEMP))
    bench.run(0.02)
    assert bench.controller.state is S.TRIPPED
    cause = f"node fault OVERTEMP (fault bits {bits!r})"
    assert bench.controller.trip_cause == cause
    assert [(e.source, e.message) for e in trips(bench)] == [("node", cause)]
    assert bench.controller.machine.history[-1].reason == cause
    bench.run(0.2, state=NodeState.FAULT)
    bench.controller.reset()
    bench.run(0.2, state=NodeState.DISABLED)
    last = bench.controller.machine.history[-1]
    assert (last.source, last.target, last.reason) == (
        S.TRIPPED, S.DISABLED, "reset complete: node DISABLED, causes cleared"
    )


def test_a_node_found_in_any_state_but_disabled_at_connect_trips_naming_that_state(bench: ScriptedNode) -> None:
    bench.run(0.2, state=NodeState.ARMED)
    assert bench.controller.state is S.TRIPPED
    cause = "node found in state ARMED at connect: expected DISABLED"
    assert bench.controller.trip_cause == cause
    assert [(e.source, e.message) for e in trips(bench)] == [("node", cause)]


def test_after_a_disarm_the_controller_stays_armed_until_the_node_reports_disabled(bench: ScriptedNode) -> None:
    """The controller shows DISABLED (safe to approach) only once the node is: a status the node sent before it
    took the DISARM still says ARMED, and so does the controller."""
    bench.armed()
    before = len(bench.controller.machine.history)
    bench.controller.disarm()
    bench.run(0.1, state=NodeState.ARMED)
    assert bench.controller.state is S.ARMED
    assert len(bench.controller.machine.history) == before  # not DISABLED for a moment either
    bench.run(0.1, state=NodeState.DISABLED)
    assert [(t.source, t.target) for t in bench.controller.machine.history[before:]] == [(S.ARMED, S.DISABLED)]


def state(bench: ScriptedNode) -> ControllerState:
    """The controller's state now (a call: mypy does not narrow it across the steps between)."""
    return bench.controller.state


def test_a_disarm_overtaken_by_a_stop_ends_disabled_not_in_a_trip(bench: ScriptedNode) -> None:
    """DISARM, then STOP before the node answers: the node takes the DISARM (DISABLED, at rest), then the STOP,
    which changes nothing there. DISABLED confirms both, so the controller is DISABLED, not tripped as if the
    node had restarted (SAFETY requirement 18: the node did what was commanded)."""
    bench.armed()
    bench.controller.disarm()
    bench.controller.stop()
    assert state(bench) is S.STOPPING
    bench.run(0.2, state=NodeState.DISABLED)
    assert trips(bench) == []
    last = bench.controller.machine.history[-1]
    assert (last.source, last.target, last.reason) == (
        S.STOPPING, S.DISABLED, "node DISABLED: it took the DISARM sent before the STOP (at rest, disabled)"
    )
    bench.run(2.0, state=NodeState.DISABLED)  # past every confirmation bound and the stop's deadline
    assert state(bench) is S.DISABLED
    assert trips(bench) == []
    assert bench.messages(EStop) == []
    bench.controller.arm()
    bench.run(0.2, state=NodeState.ARMED)
    bench.controller.set_speeds(20.0, 100.0)  # the stop is over: its ceiling no longer bounds the drives
    bench.run(1.0, follow=True)
    assert state(bench) is S.RUNNING
    assert trips(bench) == []


def test_a_node_that_restarts_just_after_a_disarm_and_an_arm_trips_naming_a_restart(bench: ScriptedNode) -> None:
    """A DISARM confirmed less than one confirmation bound ago still explains ARMED → DISABLED to the
    change check; only the DISARM of the current ARMED spell is taken as the node's answer. After disarm and
    arm, a node that reports DISABLED again restarted (or another sender disarmed it): a trip, the node's."""
    bench.armed()
    bench.controller.disarm()
    bench.run(0.1, state=NodeState.DISABLED)
    bench.controller.arm()
    bench.run(0.1, state=NodeState.ARMED)
    assert state(bench) is S.ARMED
    bench.run(0.1, state=NodeState.DISABLED)
    assert state(bench) is S.TRIPPED
    cause = (
        "node reports DISABLED while the controller is ARMED with no DISARM of its own pending: "
        "the node restarted, or another sender disarmed it"
    )
    assert [(e.source, e.message) for e in trips(bench)] == [("node", cause)]


def test_a_disarm_lost_before_a_trip_does_not_explain_a_restart_after_the_reset(bench: ScriptedNode) -> None:
    """A DISARM the node never took trips when its bound passes; the reset that follows disarms the node
    itself. That DISARM is the reset's: a node that reports DISABLED again after the next arm trips."""
    bench.armed()
    bench.controller.disarm()
    bench.run(1.5, state=NodeState.ARMED)  # the node never takes it
    assert state(bench) is S.TRIPPED
    bench.controller.reset()  # the node is ARMED: the reset disarms it
    bench.run(0.1, state=NodeState.ARMED)
    bench.run(0.1, state=NodeState.DISABLED)
    assert state(bench) is S.DISABLED
    bench.controller.arm()
    bench.run(0.1, state=NodeState.ARMED)
    bench.run(0.1, state=NodeState.DISABLED)
    assert state(bench) is S.TRIPPED
    assert trips(bench)[-1].source == "node"
    assert "the node restarted" in bench.controller.trip_cause

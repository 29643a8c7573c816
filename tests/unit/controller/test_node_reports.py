"""What a NodeStatus makes the controller do, and how it is recorded (SAFETY requirement 9).

Every state change the node's report causes is kept in the controller's history with the node's report as
its reason, and every trip a report causes names the node as its source and says what the node reported:
the operator reads why the mill stopped from the record, not from the code.
"""

from __future__ import annotations

from millctl.controller import ControllerState, Event, EventKind
from millctl.protocol import FaultCode, FaultFlag, NodeState, NodeStatus
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

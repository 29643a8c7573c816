"""A node heard again after it fell silent is judged afresh (millctl/controller/controller.py, _judge_node_change).

Silence makes the telemetry stale: the controller trips and forgets the
node's state. The first status it hears then is judged on its own: RUNNING,
with nothing commanded, is a node nobody told to run (an E-stop, as a stop
was already commanded by the trip); any other state is no cause.
"""

from __future__ import annotations

from millctl.controller import ControllerState
from millctl.protocol import NodeState
from tests.unit.controller.bench import ScriptedNode

UNCOMMANDED = "node reports RUNNING, which the controller"


def silent_after_arming(bench: ScriptedNode) -> None:
    bench.run(0.2, state=NodeState.DISABLED)
    bench.controller.arm()
    bench.run(0.2, state=NodeState.ARMED)
    bench.run(2.0)  # the node falls silent: stale, a trip, its state forgotten
    assert bench.controller.state is ControllerState.TRIPPED
    assert "stale" in bench.controller.trip_cause


def uncommanded_running_reported(bench: ScriptedNode) -> bool:
    return any(UNCOMMANDED in e.message for e in bench.events)


def test_a_node_heard_again_running_after_silence_is_a_node_nobody_told_to_run(bench: ScriptedNode) -> None:
    silent_after_arming(bench)
    assert not uncommanded_running_reported(bench)
    bench.run(0.3, state=NodeState.RUNNING)
    assert uncommanded_running_reported(bench)


def test_a_node_heard_again_armed_after_silence_is_no_cause(bench: ScriptedNode) -> None:
    silent_after_arming(bench)
    bench.run(0.3, state=NodeState.ARMED)
    assert not uncommanded_running_reported(bench)

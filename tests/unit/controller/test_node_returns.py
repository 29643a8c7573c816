"""A node heard again after it fell silent is judged afresh (millctl/controller/controller.py, _judge_node_change).

Silence makes the telemetry stale: the controller trips and forgets the
node's state. The first status it hears then is judged on its own: RUNNING,
with nothing commanded, is a node nobody told to run (an E-stop, as a stop
was already commanded by the trip); any other state is no cause.
"""

from __future__ import annotations

import pytest

from millctl.config import MillConfig
from millctl.controller import CommandRefused, ControllerState
from millctl.protocol import FurnaceTelemetry, NodeState, NodeStatus
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


def test_a_reset_while_the_node_is_still_silent_is_refused_naming_the_stale_stream(bench: ScriptedNode) -> None:
    silent_after_arming(bench)
    with pytest.raises(CommandRefused, match=r"^reset refused: .*stale"):
        bench.controller.reset()
    assert bench.controller.state is ControllerState.TRIPPED


def test_a_node_whose_drive_telemetry_never_comes_trips_after_the_start_up_grace(
    bench: ScriptedNode, config: MillConfig
) -> None:
    """The trip's stop then begins with no measured speed at all: its ceiling starts from what was commanded."""
    steps = round((config.interlock.startup_grace_s + 0.3) / 0.01)
    for i in range(steps):
        if i % 5 == 0:
            bench.say(NodeStatus(NodeState.DISABLED))
            bench.say(FurnaceTelemetry(25.0, 25.0, 0.0, False))
        bench.controller.tick()
        bench.clock.advance(0.01)
    assert bench.controller.measured is None
    assert bench.controller.state is ControllerState.TRIPPED
    assert "DriveTelemetry stale: never received" in bench.controller.trip_cause


def test_a_node_heard_again_running_on_the_setpoint_a_stop_overtook_holds_the_stop(config: MillConfig) -> None:
    # staleness short and the STOP's bound long, so that the node is lost and heard again inside that bound
    interlock = config.interlock.model_copy(update={"stale_periods": 2.0, "min_stale_s": 0.3, "command_confirm_s": 2.0})
    bench = ScriptedNode(config.model_copy(update={"interlock": interlock}))
    try:
        bench.armed()
        bench.controller.set_speeds(10.0, 100.0)
        bench.run(0.15, state=NodeState.ARMED)  # a moving setpoint sent, not yet taken
        bench.controller.stop()
        bench.run(0.5)  # the node silent: every stream stale, the node's history forgotten
        assert bench.controller.state is ControllerState.TRIPPED
        heard = len(bench.events)
        bench.run(0.1, state=NodeState.RUNNING, rotary_rpm=1.0, vibration_rpm=10.0)
        [held] = [e for e in bench.events[heard:] if e.message.startswith("node RUNNING")]
        assert "after the STOP, on the setpoint sent before it" in held.message and held.source == "controller"
        assert "did not command" not in bench.controller.trip_cause  # not taken for an uncommanded run
    finally:
        bench.close()

"""An E-stop is repeated until the node reports it (issue 15 item 2), and its frame says who asked for it."""

from __future__ import annotations

from millctl.controller import ControllerState
from millctl.protocol import DriveTelemetry, EStop, EStopSource, FaultFlag, FurnaceTelemetry, NodeState, NodeStatus
from tests.unit.controller.bench import ScriptedNode


def report_estop(bench: ScriptedNode, seconds: float) -> None:
    """The node in FAULT with the E-stop's bit set, every 50 ms."""
    for _ in range(round(seconds / 0.05)):
        bench.say(NodeStatus(NodeState.FAULT, FaultFlag.ESTOP))
        bench.say(DriveTelemetry(0.0, 0.0))
        bench.say(FurnaceTelemetry(25.0, 25.0, 0.0, False))
        bench.run(0.05)


def test_an_operators_estop_is_repeated_until_the_node_reports_it(bench: ScriptedNode) -> None:
    bench.armed()
    bench.controller.estop()
    assert bench.controller.state is ControllerState.TRIPPED
    bench.run(0.6, state=NodeState.FAULT)  # FAULT, but without the E-stop's bit: not yet acted on
    repeated = len(bench.messages(EStop))
    repeat_s = bench.controller.config.interlock.command_repeat_s
    # the first and one a repeat period (0.2 s) after it, not one a controller tick (0.01 s)
    assert 3 <= repeated <= 2 + 0.6 / repeat_s, f"{repeated} E-stops in 0.6 s, one every {repeat_s} s expected"
    report_estop(bench, 0.2)
    reported = len(bench.messages(EStop))
    report_estop(bench, 0.6)
    assert len(bench.messages(EStop)) == reported  # reported: no more
    sent = bench.messages(EStop)
    assert sent[0] == EStop(EStopSource.OPERATOR)  # who asked, on the wire
    assert set(sent[1:]) == {EStop(EStopSource.CONTROLLER)}  # the repeats are the controller's


def test_the_controllers_own_estop_says_so_on_the_wire(bench: ScriptedNode) -> None:
    bench.armed()
    bench.controller.estop("controller")
    bench.collect()
    assert bench.messages(EStop) == [EStop(EStopSource.CONTROLLER)]

"""Every command confirmed, only what was commanded believed: the controller against a scripted node.

Issue 15 items 2 and 5 (docs/safety.md#every-command-confirmed, #believe-only-what-was-commanded).
"""

from __future__ import annotations

import pytest

from millctl.config import MillConfig
from millctl.controller import CommandRefused, ControllerState, EventKind
from millctl.protocol import Command, CommandCode, EStop, FurnaceTelemetry, NodeState, NodeStatus
from millctl.safety import InterlockRefused
from tests.unit.controller.bench import ScriptedNode

S = ControllerState


def sent_commands(bench: ScriptedNode, code: CommandCode) -> int:
    return bench.messages(Command).count(Command(code))


def running(bench: ScriptedNode, rotary_rpm: float = 100.0, vibration_rpm: float = 400.0) -> None:
    bench.run(0.2, state=NodeState.DISABLED)
    bench.controller.arm()
    bench.run(0.2, state=NodeState.ARMED)
    move = bench.controller.set_speeds(rotary_rpm, vibration_rpm)
    bench.run(move.duration_s + 0.5, follow=True)
    assert bench.controller.state is S.RUNNING, bench.controller.trip_cause


def test_an_arm_the_node_never_confirms_is_repeated_then_trips_naming_it(
    bench: ScriptedNode, config: MillConfig
) -> None:
    bench.run(0.2, state=NodeState.DISABLED)
    bench.controller.arm()
    bench.run(config.interlock.command_confirm_s - 0.05, state=NodeState.DISABLED)
    assert bench.controller.state is S.DISABLED
    repeats = config.interlock.command_confirm_s / config.interlock.command_repeat_s
    assert sent_commands(bench, CommandCode.ARM) >= int(repeats) - 1  # sent again while unconfirmed
    bench.run(0.1, state=NodeState.DISABLED)
    assert bench.controller.state is S.TRIPPED
    assert "ARM" in bench.controller.trip_cause and "not confirmed" in bench.controller.trip_cause
    assert f"after {sent_commands(bench, CommandCode.ARM)} send(s)" in bench.controller.trip_cause


def test_a_confirmed_command_is_not_repeated(bench: ScriptedNode) -> None:
    bench.run(0.2, state=NodeState.DISABLED)
    bench.controller.arm()
    bench.run(2.0, state=NodeState.ARMED)
    assert bench.controller.state is S.ARMED
    assert sent_commands(bench, CommandCode.ARM) == 1


def test_a_node_that_arms_uncommanded_trips(bench: ScriptedNode) -> None:
    bench.run(0.2, state=NodeState.DISABLED)
    bench.run(0.2, state=NodeState.ARMED)  # nobody sent ARM
    assert bench.controller.state is S.TRIPPED
    assert "DISABLED → ARMED" in bench.controller.trip_cause


def test_a_node_that_does_not_take_its_setpoints_trips(bench: ScriptedNode) -> None:
    bench.run(0.2, state=NodeState.DISABLED)
    bench.controller.arm()
    bench.run(0.2, state=NodeState.ARMED)
    bench.controller.set_speeds(100.0, 400.0)
    window_s = bench.controller.expectation.window_s
    bench.run(window_s + 4.0, state=NodeState.ARMED)  # it stays at rest, ARMED
    assert bench.controller.state is S.TRIPPED
    assert "did not take its setpoints" in bench.controller.trip_cause


def test_a_drive_faster_than_commanded_trips(bench: ScriptedNode) -> None:
    running(bench)
    bench.run(0.2, state=NodeState.RUNNING, rotary_rpm=100.0, vibration_rpm=430.0)  # inside the envelope
    assert bench.controller.state is S.TRIPPED
    assert "is not what was commanded" in bench.controller.trip_cause


def test_stopping_has_a_deadline(bench: ScriptedNode) -> None:
    running(bench)
    bench.controller.stop()
    bound_s = bench.controller.expectation.stop_bound_s
    bench.run(bound_s - 0.2, state=NodeState.STOPPING)  # it says STOPPING, at rest, and never finishes
    assert bench.controller.state is S.STOPPING
    bench.run(0.4, state=NodeState.STOPPING)
    assert bench.controller.state is S.TRIPPED
    assert "controlled stop not complete by its deadline" in bench.controller.trip_cause
    assert "node STOPPING, measured 0.0/0.0 rpm" in bench.controller.trip_cause  # what the operator needs to see
    assert any(d.kind is EStop for _, d in bench.sent)


def test_a_stop_deadline_passed_before_any_drive_telemetry_says_the_speeds_are_unknown(config: MillConfig) -> None:
    # a start-up grace longer than the stop's bound: the deadline comes before the silent stream goes stale
    patient = config.model_copy(update={"interlock": config.interlock.model_copy(update={"startup_grace_s": 10.0})})
    bench = ScriptedNode(patient)
    try:

        def node_says(state: NodeState, seconds: float) -> None:  # status and furnace, never DriveTelemetry
            for _ in range(round(seconds / 0.05)):
                bench.say(NodeStatus(state))
                bench.say(FurnaceTelemetry(25.0, 25.0, 0.0, False))
                bench.run(0.05)

        node_says(NodeState.DISABLED, 0.2)
        bench.controller.arm()
        node_says(NodeState.ARMED, 0.2)
        bench.controller.stop()
        node_says(NodeState.STOPPING, bench.controller.expectation.stop_bound_s + 0.3)
        assert bench.controller.measured is None
        assert bench.controller.state is S.TRIPPED
        assert "controlled stop not complete by its deadline" in bench.controller.trip_cause
        assert "node STOPPING, measured unknown" in bench.controller.trip_cause
    finally:
        bench.close()


def test_a_drive_that_does_not_slow_down_in_stopping_is_an_estop(bench: ScriptedNode) -> None:
    running(bench)
    bench.controller.stop()
    bench.run(
        bench.controller.expectation.stop_bound_s + 0.5, state=NodeState.STOPPING, rotary_rpm=100.0, vibration_rpm=400.0
    )
    assert bench.controller.state is S.TRIPPED
    assert "stop ceiling" in bench.controller.trip_cause and "E-stop" in bench.controller.trip_cause


def test_the_envelope_is_checked_in_stopping(bench: ScriptedNode, config: MillConfig) -> None:
    running(bench, 180.0, 800.0)
    bench.controller.stop()
    for _ in range(config.interlock.debounce_samples):
        bench.alive(NodeState.STOPPING, rotary_rpm=180.0, vibration_rpm=500.0)  # ω_v fell under ω_r's limit
        bench.controller.tick()
    assert bench.controller.state is S.TRIPPED
    assert "measured speeds outside the envelope" in bench.controller.trip_cause


def test_the_heating_rate_is_checked(bench: ScriptedNode) -> None:
    running(bench)
    with pytest.raises(InterlockRefused, match=r"heating rate 1000\.0 °C/min must be in"):
        bench.controller.set_furnace(200.0, rate_c_per_min=1000.0)
    assert bench.controller.furnace_target_c is None
    bench.controller.set_furnace(200.0, rate_c_per_min=10.0)
    assert bench.controller.furnace_target_c == 200.0


def test_disarm_needs_both_setpoints_at_standstill(bench: ScriptedNode) -> None:
    bench.run(0.2, state=NodeState.DISABLED)
    bench.controller.arm()
    bench.run(0.2, state=NodeState.ARMED)
    bench.controller.set_speeds(0.0, 100.0)
    with pytest.raises(CommandRefused, match="disarm needs both setpoints at 0"):
        bench.controller.disarm()
    assert sent_commands(bench, CommandCode.DISARM) == 0


def test_speeds_set_while_a_disarm_is_pending_are_refused_not_dropped(bench: ScriptedNode) -> None:
    """The node disarms at rest and then refuses every setpoint: a ramp accepted between the DISARM and the
    node's answer would be dropped without a word (SAFETY requirement 20). It is refused, and recorded."""
    bench.run(0.2, state=NodeState.DISABLED)
    bench.controller.arm()
    bench.run(0.2, state=NodeState.ARMED)
    bench.controller.disarm()
    with pytest.raises(CommandRefused, match="while a DISARM is pending"):
        bench.controller.set_speeds(20.0, 100.0, source="api:bob")
    assert bench.controller.trajectory is None
    assert [(e.source, e.message) for e in bench.events if e.kind is EventKind.REFUSAL] == [
        ("api:bob", "set speeds is not possible while a DISARM is pending: arm again once the node reports DISABLED")
    ]
    bench.run(0.2, state=NodeState.DISABLED)
    assert bench.controller.state is S.DISABLED
    bench.controller.arm()
    bench.run(0.2, state=NodeState.ARMED)
    bench.controller.set_speeds(20.0, 100.0)  # armed again: taken
    assert bench.controller.trajectory is not None


def test_an_e2e_faulted_node_link_trips(bench: ScriptedNode, config: MillConfig) -> None:
    from millctl.protocol import NodeStatus

    bench.run(0.2, state=NodeState.DISABLED)
    for _ in range(config.interlock.e2e_error_limit):
        frame = bench.codec.encode(NodeStatus(NodeState.DISABLED), 3)
        frame.data[0] ^= 0xFF  # a bad CRC
        bench.bus.send(frame)
        bench.controller.tick()
    assert bench.controller.state is S.TRIPPED
    assert "NodeStatus E2E error score" in bench.controller.trip_cause


def test_every_escalation_is_recorded(bench: ScriptedNode) -> None:
    running(bench)
    bench.controller.stop()
    bench.run(
        bench.controller.expectation.stop_bound_s + 0.5, state=NodeState.STOPPING, rotary_rpm=100.0, vibration_rpm=400.0
    )
    trips = [e for e in bench.events if e.kind is EventKind.TRIP]
    assert trips and trips[0].message.startswith("E-stop:")


def test_a_reset_forgets_the_debounce_counts(config: MillConfig) -> None:
    """After reset, a trip needs the full debounce count again (kills the reset mutants of both monitors)."""
    from millctl.controller.expect import SpeedExpectation
    from millctl.controller.monitor import MeasuredSpeedMonitor
    from millctl.safety import STANDSTILL, Envelope, RampPlanner, SpeedPoint

    envelope = Envelope.from_config(config)
    n = config.interlock.debounce_samples
    monitor = MeasuredSpeedMonitor(envelope, n)
    expectation = SpeedExpectation(RampPlanner(envelope), 3.0, 2.0, n)
    expectation.commanded(0.0, STANDSTILL)
    for _ in range(n - 1):
        assert monitor.update(260.0, 800.0) is None
        assert expectation.check(0.0, 50.0, 0.0) is None
    monitor.reset()
    expectation.reset()
    assert monitor.outside_in_a_row == 0 and expectation.outside_in_a_row == 0
    assert monitor.update(260.0, 800.0) is None  # one outside sample after the reset does not trip
    assert expectation.check(0.0, 50.0, 0.0) is None
    # a drive at rest though commanded to turn counts a whole window from after the reset
    expectation.commanded(10.0, SpeedPoint(0.0, 400.0))
    expectation.commanded(12.5, SpeedPoint(0.0, 400.0))
    expectation.check(12.5, 0.0, 0.0)
    expectation.reset()
    assert expectation.check(13.0, 0.0, 0.0) is None
    assert expectation.check(15.0, 0.0, 0.0) is not None

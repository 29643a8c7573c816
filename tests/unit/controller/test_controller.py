"""The controller against a scripted node: heartbeat, interlock, trips, latching, reset."""

from __future__ import annotations

import pytest

from millctl.config import MillConfig
from millctl.controller import CommandRefused, ControllerState, EventKind
from millctl.protocol import Command, CommandCode, Heartbeat, NodeState, NodeStatus, Setpoints
from millctl.safety import InterlockRefused
from tests.unit.controller.bench import ScriptedNode

S = ControllerState


def test_heartbeat_20_hz_counter_advanced_by_the_loop(bench: ScriptedNode) -> None:
    bench.run(1.0)
    beats = bench.of(Heartbeat)
    assert len(beats) == 20
    counters = [d.counter for _, d in beats]
    assert counters == [i % 16 for i in range(20)]
    # no tick, no heartbeat: a hung loop stops the heartbeat
    bench.clock.advance(1.0)
    bench.collect()
    assert len(bench.of(Heartbeat)) == 20


def test_each_heartbeat_echoes_the_challenge_of_the_latest_node_status(bench: ScriptedNode) -> None:
    """The node feeds its watchdog only from a heartbeat echoing a challenge it issued lately (docs/protocol.md,
    "Heartbeat freshness"): the controller echoes the newest NodeStatus's challenge, 0 before it heard one."""
    bench.run(0.2)
    assert {m.challenge_echo for m in bench.messages(Heartbeat)} == {0}
    for challenge in (4242, 17, 65535):
        bench.say(NodeStatus(NodeState.DISABLED, challenge=challenge))
        bench.run(0.1)
        assert bench.messages(Heartbeat)[-1].challenge_echo == challenge


def test_connects_when_the_node_is_seen(bench: ScriptedNode) -> None:
    assert bench.controller.state is S.DISCONNECTED
    assert bench.controller.trip_cause == ""  # the status shows no cause before any trip
    bench.run(0.2, state=NodeState.DISABLED)
    assert bench.controller.state is S.DISABLED
    assert bench.controller.trip_cause == ""


def test_arm_sends_command_and_follows_node(bench: ScriptedNode) -> None:
    bench.armed()
    assert bench.messages(Command) == [Command(CommandCode.ARM)]


def test_over_limit_setpoint_refused_and_nothing_sent(bench: ScriptedNode) -> None:
    bench.armed()
    with pytest.raises(InterlockRefused, match=r"250\.0 rpm exceeds the limit 190\.0 rpm"):
        bench.controller.set_speeds(250.0, 800.0)
    bench.run(0.5, state=NodeState.ARMED)
    sent = bench.messages(Setpoints)
    assert sent, "the controller sends its (standstill) setpoints while ARMED"
    assert all(m.rotary_rpm == 0.0 and m.vibration_rpm == 0.0 for m in sent)
    assert any(e.kind is EventKind.REFUSAL and "250.0 rpm" in e.message for e in bench.events)


def test_setpoints_follow_the_planned_ramp_at_10_hz(bench: ScriptedNode) -> None:
    bench.armed()
    move = bench.controller.set_speeds(180.0, 800.0)
    bench.run(move.duration_s + 0.5, follow=True)
    assert bench.controller.state is S.RUNNING, bench.controller.trip_cause
    sent = bench.messages(Setpoints)
    assert sent[-1].rotary_rpm == 180.0 and sent[-1].vibration_rpm == 800.0
    for m in sent:  # every sent pair is inside
        assert bench.controller.envelope.check(m.rotary_rpm, m.vibration_rpm).ok
    assert len(sent) == pytest.approx((0.4 + move.duration_s + 0.5) * 10, abs=2)


def test_commands_refused_in_the_wrong_state(bench: ScriptedNode) -> None:
    with pytest.raises(CommandRefused, match="arm is not possible in state DISCONNECTED"):
        bench.controller.arm()
    bench.run(0.2, state=NodeState.DISABLED)
    with pytest.raises(CommandRefused, match="set speeds is not possible in state DISABLED"):
        bench.controller.set_speeds(10.0, 100.0)


def test_measured_outside_trips_after_debounce(bench: ScriptedNode, config: MillConfig) -> None:
    bench.armed()
    move = bench.controller.set_speeds(180.0, 800.0)
    bench.run(move.duration_s + 0.5, follow=True)
    n = config.interlock.debounce_samples
    for i in range(n):
        assert bench.controller.state is not S.TRIPPED, i
        bench.alive(NodeState.RUNNING, rotary_rpm=260.0, vibration_rpm=800.0)
        bench.controller.tick()
        bench.collect()
    assert bench.controller.state is S.TRIPPED
    assert "measured speeds outside the envelope for 3 samples" in bench.controller.trip_cause
    assert Command(CommandCode.STOP) in bench.messages(Command)


def test_a_single_outlier_does_not_trip(bench: ScriptedNode) -> None:
    bench.armed()
    bench.alive(NodeState.ARMED, rotary_rpm=260.0, vibration_rpm=800.0)
    bench.run(0.5, state=NodeState.ARMED)
    assert bench.controller.state is S.ARMED


def test_stale_telemetry_trips_and_latches(bench: ScriptedNode) -> None:
    bench.armed()
    bench.run(2.0)  # the node falls silent
    assert bench.controller.state is S.TRIPPED
    assert "stale" in bench.controller.trip_cause
    bench.run(1.0, state=NodeState.ARMED)  # it comes back: still latched
    assert bench.controller.state is S.TRIPPED
    with pytest.raises(CommandRefused, match="reset first"):
        bench.controller.set_speeds(10.0, 100.0)


def test_node_fault_trips_with_its_cause(bench: ScriptedNode) -> None:
    from millctl.protocol import FaultCode, FaultFlag, NodeStatus

    bench.armed()
    bench.say(NodeStatus(NodeState.FAULT, FaultFlag.STALL, FaultCode.STALL))
    bench.run(0.05)
    assert bench.controller.state is S.TRIPPED and "STALL" in bench.controller.trip_cause


def test_reset_needs_standstill_and_fresh_telemetry(bench: ScriptedNode) -> None:
    bench.armed()
    bench.run(2.0)
    assert bench.controller.state is S.TRIPPED
    bench.alive(NodeState.FAULT, rotary_rpm=50.0)
    bench.run(0.05)
    with pytest.raises(CommandRefused, match="not at standstill"):
        bench.controller.reset()
    bench.run(0.2, state=NodeState.FAULT)
    bench.controller.reset()
    bench.collect()
    assert Command(CommandCode.RESET) in bench.messages(Command)
    bench.run(0.2, state=NodeState.DISABLED)
    assert bench.controller.state is S.DISABLED


def test_node_restart_mid_run_trips(bench: ScriptedNode) -> None:
    bench.armed()
    bench.controller.set_speeds(100.0, 400.0)
    bench.run(0.5, state=NodeState.RUNNING)
    bench.run(0.2, state=NodeState.DISABLED)  # a fresh node boots DISABLED
    assert bench.controller.state is S.TRIPPED
    assert "restarted" in bench.controller.trip_cause


def test_every_state_change_has_a_reason(bench: ScriptedNode) -> None:
    bench.armed()
    changes = [e for e in bench.events if e.kind is EventKind.STATE]
    assert [e.data["target_state"] for e in changes] == ["DISABLED", "ARMED"]
    assert all(e.data["reason"] for e in changes)


def test_reset_before_the_node_reports_its_fault_is_completed_when_it_does(bench: ScriptedNode) -> None:
    bench.armed()
    bench.controller.estop()
    bench.controller.reset()  # the node has not reported FAULT yet: nothing to send so far
    bench.collect()
    assert Command(CommandCode.RESET) not in bench.messages(Command)
    bench.run(0.2, state=NodeState.FAULT)
    assert bench.messages(Command).count(Command(CommandCode.RESET)) == 1
    bench.run(0.2, state=NodeState.DISABLED)
    assert bench.controller.state is S.DISABLED


def test_a_completed_reset_is_confirmed_once_and_not_sent_again(bench: ScriptedNode) -> None:
    bench.armed()
    bench.controller.estop()
    bench.run(0.2, state=NodeState.FAULT)
    bench.controller.reset()
    bench.run(0.2, state=NodeState.DISABLED)
    assert bench.controller.state is S.DISABLED
    bench.run(2.0, state=NodeState.DISABLED)  # past the confirmation bound: nothing pending, nothing lost
    assert bench.controller.state is S.DISABLED, bench.controller.trip_cause
    assert bench.messages(Command).count(Command(CommandCode.RESET)) == 1


def test_a_completed_reset_clears_the_trip_cause_and_is_never_reported_as_given_up(bench: ScriptedNode) -> None:
    from millctl.controller.controller import RESET_TIMEOUT_S

    bench.armed()
    bench.controller.estop()
    bench.run(0.2, state=NodeState.FAULT)
    assert bench.controller.trip_cause
    bench.controller.reset()
    bench.run(0.2, state=NodeState.DISABLED)
    assert bench.controller.state is S.DISABLED
    assert bench.controller.trip_cause == ""  # the status shows no cause once the reset is done
    bench.run(RESET_TIMEOUT_S + 0.5, state=NodeState.DISABLED)
    refusals = [e.message for e in bench.events if e.kind is EventKind.REFUSAL]
    assert not [m for m in refusals if "reset did not complete" in m], refusals


def test_a_node_disabled_with_a_fault_still_latched_has_not_confirmed_the_reset(bench: ScriptedNode) -> None:
    from millctl.protocol import DriveTelemetry, FaultFlag, FurnaceTelemetry, NodeStatus

    bench.armed()
    bench.controller.estop()
    bench.run(0.2, state=NodeState.FAULT)
    bench.controller.reset()
    for _ in range(10):  # 0.5 s of DISABLED with the WATCHDOG bit still set
        bench.say(NodeStatus(NodeState.DISABLED, FaultFlag.WATCHDOG))
        bench.say(DriveTelemetry(0.0, 0.0))
        bench.say(FurnaceTelemetry(25.0, 25.0, 0.0, False))
        bench.run(0.05)
    assert bench.messages(Command).count(Command(CommandCode.RESET)) >= 2  # still pending: sent again


def test_a_reset_the_node_never_completes_is_given_up_with_its_reason(bench: ScriptedNode) -> None:
    bench.armed()
    bench.controller.estop()
    bench.run(0.2, state=NodeState.FAULT)
    bench.controller.reset()
    bench.run(3.0, state=NodeState.FAULT)  # the node keeps its fault
    assert bench.controller.state is S.TRIPPED
    assert any(e.kind is EventKind.REFUSAL and "reset did not complete" in e.message for e in bench.events)


def test_a_reset_given_up_unconfirmed_is_over_and_recorded_once(bench: ScriptedNode, config: MillConfig) -> None:
    """A RESET the node does not confirm within interlock.command_confirm_s gives the reset up: the operator is
    told once to clear the cause and retry, and a node that turns up DISABLED and clear afterwards does not
    complete the given-up reset behind the operator's back (docs/safety.md#mutation-testing: `_lost`)."""
    from millctl.controller.controller import RESET_TIMEOUT_S

    bench.armed()
    bench.controller.estop()
    bench.run(0.2, state=NodeState.FAULT)
    bench.controller.reset()
    lost_s = config.interlock.command_confirm_s + 0.3
    assert lost_s + 0.3 < RESET_TIMEOUT_S  # the confirmation bound gives up first, before the reset's own timeout
    bench.run(lost_s, state=NodeState.FAULT)  # the node refuses the RESET: its cause is still there

    def given_up() -> list[str]:
        refusals = [e.message for e in bench.events if e.kind is EventKind.REFUSAL]
        return [message for message in refusals if "reset did not complete" in message]

    assert len(given_up()) == 1 and "RESET" in given_up()[0], [e.message for e in bench.events]
    bench.run(0.3, state=NodeState.DISABLED)  # DISABLED and clear, after the reset was given up
    assert bench.controller.state is S.TRIPPED
    bench.run(RESET_TIMEOUT_S, state=NodeState.DISABLED)
    assert bench.controller.state is S.TRIPPED
    assert len(given_up()) == 1, given_up()


def test_a_reset_with_nothing_to_send_that_the_node_never_completes_is_given_up_after_its_timeout(
    bench: ScriptedNode,
) -> None:
    """The reset's own bound: a node already DISABLED needs no command, so no confirmation bound gives the
    reset up; when its completing status never comes (the node falls silent), RESET_TIMEOUT_S does."""
    from millctl.controller.controller import RESET_TIMEOUT_S

    bench.armed()
    bench.run(0.2, state=NodeState.DISABLED)  # the node restarted: a trip
    assert bench.controller.state is S.TRIPPED
    commands_before = len(bench.messages(Command))
    bench.controller.reset()
    bench.run(RESET_TIMEOUT_S + 0.1)  # not a word from the node
    assert len(bench.messages(Command)) == commands_before  # nothing to send, so nothing to confirm
    given_up = [e for e in bench.events if e.kind is EventKind.REFUSAL and "reset did not complete within" in e.message]
    assert len(given_up) == 1, [e.message for e in bench.events]
    assert given_up[0].source == "operator"  # recorded as the refusal of the operator's reset
    assert given_up[0].message.endswith(  # what the node said last, for the operator to act on
        "node DISABLED, last refusal NONE; clear the cause and retry"
    )
    bench.run(0.5, state=NodeState.DISABLED)  # the node is back, DISABLED and clear: the reset was given up
    assert bench.controller.state is S.TRIPPED


def _without_furnace(bench: ScriptedNode, seconds: float) -> None:
    """The node's NodeStatus and DriveTelemetry every 50 ms, its FurnaceTelemetry not (yet)."""
    from millctl.protocol import DriveTelemetry, NodeStatus

    for i in range(round(seconds / 0.01)):
        if i % 5 == 0:
            bench.say(NodeStatus(NodeState.DISABLED))
            bench.say(DriveTelemetry(0.0, 0.0))
        bench.controller.tick()
        bench.clock.advance(0.01)


def test_start_up_waits_for_every_stream_before_judging_staleness(bench: ScriptedNode) -> None:
    """Issue 15 item 9: a stream that starts later than NodeStatus is not 'stale: never received' at start."""
    _without_furnace(bench, 0.5)
    assert bench.controller.state is S.DISABLED, bench.controller.trip_cause
    bench.run(3.0, state=NodeState.DISABLED)  # the furnace stream begins
    assert bench.controller.state is S.DISABLED, bench.controller.trip_cause


def test_a_stream_that_never_comes_is_a_fault_after_the_start_up_grace(bench: ScriptedNode, config: MillConfig) -> None:
    grace_s = config.interlock.startup_grace_s
    _without_furnace(bench, grace_s - 0.1)
    assert bench.controller.state is S.DISABLED
    _without_furnace(bench, 0.2)
    assert bench.controller.state is S.TRIPPED
    assert "FurnaceTelemetry stale: never received" in bench.controller.trip_cause
    assert "interlock.startup_grace_s" in bench.controller.trip_cause


def test_a_malformed_frame_is_counted_named_and_the_frames_after_it_are_still_taken(bench: ScriptedNode) -> None:
    """SAFETY 19 and 22: bad input is counted, never raised, and does not end the drain; a node fault that
    arrives right behind a malformed frame is acted on in the same tick."""
    import can

    from millctl.protocol import FaultCode, FaultFlag

    bench.armed()
    whole = bench.codec.encode(NodeStatus(NodeState.ARMED), 0)
    short = can.Message(arbitration_id=whole.arbitration_id, data=bytes(whole.data[:1]), is_extended_id=False)
    bench.bus.send(short)  # one byte where the DBC has eight
    bench.say(NodeStatus(NodeState.FAULT, FaultFlag.STALL, FaultCode.STALL))
    bench.controller.tick()
    assert bench.controller.state is S.TRIPPED and "STALL" in bench.controller.trip_cause
    assert bench.controller.invalid_frames == 1
    error = bench.controller.reader.counts.last_error
    assert error == "malformed frame: 0x100: frame 0x100 (NodeStatus): length 1, expected 8 bytes"

"""A STOP that overtakes the controller's own order to run, against a scripted node (issue 15).

The node takes frames in order: a RUNNING that answers the controller's own
nonzero setpoint, sent to an ARMED node just before a STOP, is no forgery;
every other RUNNING the controller did not command still trips
(docs/safety.md#a-stop-overtaking-a-setpoint).
"""

from __future__ import annotations

import re

from millctl.config import MillConfig
from millctl.controller import ControllerState, EventKind
from millctl.protocol import Command, CommandCode, DriveTelemetry, NodeState, Setpoints
from tests.unit.controller.bench import ScriptedNode

S = ControllerState


def state(bench: ScriptedNode) -> ControllerState:
    """The controller's state now (a call, so a type checker does not carry one assert's state to the next)."""
    return bench.controller.state


def ordered_then_stopped(bench: ScriptedNode) -> None:
    """ARMED; a ramp whose first nonzero setpoint goes out while the node still reports ARMED; then STOP."""
    bench.armed()
    bench.controller.set_speeds(100.0, 400.0)
    for _ in range(100):
        bench.run(0.01)
        if any(s.rotary_rpm > 0.0 or s.vibration_rpm > 0.0 for s in bench.messages(Setpoints)):
            break
    assert state(bench) is S.ARMED
    bench.controller.stop()
    assert state(bench) is S.STOPPING


def stops_sent(bench: ScriptedNode) -> int:
    return bench.messages(Command).count(Command(CommandCode.STOP))


def test_running_on_the_setpoint_a_stop_overtook_is_no_forgery(bench: ScriptedNode) -> None:
    """The seen flake: 'node went ARMED → RUNNING, which the controller (state STOPPING) did not command'."""
    ordered_then_stopped(bench)
    bench.run(0.1, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)  # took the setpoint, then
    bench.run(0.1, state=NodeState.STOPPING)  # the STOP
    bench.run(0.3, state=NodeState.ARMED)
    assert state(bench) is S.ARMED, bench.controller.trip_cause
    assert bench.controller.estops_sent == 0
    held = [e for e in bench.events if e.kind is EventKind.COMMAND and "the stop holds" in e.message]
    assert len(held) == 1 and held[0].source == "controller"  # the controller's own judgement, recorded once
    assert re.fullmatch(
        r"node RUNNING 0\.\d\d s after the STOP, on the setpoint sent before it \(the node takes frames in "
        r"order and has not taken the STOP yet\): the stop holds, STOP pending "
        r"\(docs/safety\.md#a-stop-overtaking-a-setpoint\)",
        held[0].message,
    )


def test_a_status_from_before_the_stop_does_not_end_it(bench: ScriptedNode) -> None:
    """Separate processes: an ARMED the node sent before it took the setpoint arrives after the STOP."""
    ordered_then_stopped(bench)
    bench.run(0.05, state=NodeState.ARMED)  # stale: the controller takes it for the stop's end
    assert state(bench) is S.ARMED
    bench.run(0.05, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)
    assert state(bench) is S.STOPPING  # the stop is not over: the node has not taken it
    reopened = bench.controller.confirmations.pending[CommandCode.STOP]
    assert (reopened.source, reopened.reason) == ("controller", "the node ran on a setpoint sent before the STOP")
    stop_s = bench.controller.run_orders.stop_s  # no longer than one bound from the STOP's first send
    assert reopened.deadline_s == stop_s + bench.controller.config.interlock.command_confirm_s
    assert any("the stop is not complete" in t.reason for t in bench.controller.machine.history)
    bench.run(0.2, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)
    assert stops_sent(bench) >= 2  # pending again: repeated until the node shows it took it
    bench.run(0.3, state=NodeState.ARMED)
    assert state(bench) is S.ARMED, bench.controller.trip_cause
    assert bench.controller.estops_sent == 0


def test_the_order_explains_one_running_only(bench: ScriptedNode) -> None:
    ordered_then_stopped(bench)
    bench.run(0.1, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)
    bench.run(0.1, state=NodeState.ARMED)
    bench.run(0.1, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)  # a forged setpoint now
    assert state(bench) is S.TRIPPED
    assert "ARMED → RUNNING" in bench.controller.trip_cause


def test_after_the_node_took_the_stop_running_is_a_forgery(bench: ScriptedNode) -> None:
    ordered_then_stopped(bench)
    bench.run(0.1, state=NodeState.STOPPING)  # the node took the setpoint and the STOP in one tick
    bench.run(0.1, state=NodeState.ARMED)
    bench.run(0.1, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)
    assert state(bench) is S.TRIPPED
    assert "ARMED → RUNNING" in bench.controller.trip_cause


def test_without_an_order_to_run_an_armed_node_running_in_a_stop_is_a_forgery(bench: ScriptedNode) -> None:
    bench.run(0.2, state=NodeState.DISABLED)
    bench.controller.arm()
    bench.run(0.5, state=NodeState.ARMED)
    bench.controller.stop()  # at standstill: no setpoint but zeros ever sent
    bench.run(0.1, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)
    assert state(bench) is S.TRIPPED
    assert "ARMED → RUNNING" in bench.controller.trip_cause and "E-stop" in bench.controller.trip_cause


def test_a_running_node_ordered_again_is_not_excused(bench: ScriptedNode) -> None:
    """The node had answered the order (RUNNING seen before the STOP): a later ARMED → RUNNING is nobody's."""
    bench.armed()
    bench.controller.set_speeds(20.0, 100.0)
    bench.run(1.0, follow=True)
    assert state(bench) is S.RUNNING
    bench.controller.stop()
    bench.run(0.05, state=NodeState.ARMED, rotary_rpm=0.5, vibration_rpm=2.0)
    bench.run(0.05, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)
    assert state(bench) is S.TRIPPED
    assert "ARMED → RUNNING" in bench.controller.trip_cause


def test_an_excused_running_that_does_not_end_is_an_estop_by_the_stops_deadline(
    bench: ScriptedNode, config: MillConfig
) -> None:
    ordered_then_stopped(bench)
    stopped_s = bench.clock.now()
    for _ in range(300):
        bench.run(0.05, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)
        if state(bench) is S.TRIPPED:
            break
    assert state(bench) is S.TRIPPED
    assert bench.clock.now() - stopped_s <= config.interlock.command_confirm_s + 0.1
    assert "STOP" in bench.controller.trip_cause and "not confirmed" in bench.controller.trip_cause
    assert bench.controller.estops_sent >= 1


def test_running_after_the_bound_is_a_forgery(bench: ScriptedNode, config: MillConfig) -> None:
    ordered_then_stopped(bench)
    bench.run(config.interlock.command_confirm_s + 0.1, state=NodeState.ARMED)
    assert state(bench) is S.ARMED
    bench.run(0.1, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)
    assert state(bench) is S.TRIPPED
    assert "ARMED → RUNNING" in bench.controller.trip_cause


def test_a_trips_stop_overtaking_the_order_is_no_cause_for_an_estop(bench: ScriptedNode, config: MillConfig) -> None:
    """A trip's STOP is a STOP: the node's answer to the order it overtook does not add an E-stop."""
    ordered_then_stopped(bench)
    bench.controller.stop()  # a second stop request changes nothing
    bench.run(0.1, state=NodeState.STOPPING)
    bench.run(0.1, state=NodeState.ARMED)
    assert state(bench) is S.ARMED
    bench.controller.set_speeds(100.0, 400.0)
    for _ in range(100):
        bench.run(0.01)
        if bench.messages(Setpoints)[-1].rotary_rpm > 0.0 or bench.messages(Setpoints)[-1].vibration_rpm > 0.0:
            break
    for _ in range(config.interlock.debounce_samples + 1):  # measured far above what was commanded: a trip
        bench.say(DriveTelemetry(150.0, 1500.0))
        bench.run(0.02)
    assert state(bench) is S.TRIPPED
    bench.run(0.1, state=NodeState.RUNNING, rotary_rpm=0.5, vibration_rpm=2.0)
    assert bench.controller.estops_sent == 0, bench.controller.trip_cause
    assert CommandCode.STOP in bench.controller.confirmations.pending

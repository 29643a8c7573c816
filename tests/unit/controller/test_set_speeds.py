"""Setting speeds (``Controller.set_speeds``): planned as asked, checked whole before any part applies, recorded.

Issue 15 item 7 (a refused part leaves the other untouched) and SAFETY requirement 9 (every command and
refusal recorded with who asked and what), shown on the controller alone against a scripted node.
"""

from __future__ import annotations

import pytest

from millctl.config import MillConfig
from millctl.controller import ControllerState, EventKind
from millctl.errors import InvalidInputError
from millctl.protocol import Command, DriveTelemetry, FurnaceTelemetry, NodeState, NodeStatus, Setpoints
from millctl.safety import STANDSTILL, InterlockRefused, SpeedPoint
from tests.unit.controller.bench import ScriptedNode

WHO = "api:bob"


def test_the_move_is_the_planned_corridor_from_the_commanded_point_at_the_rates_asked(bench: ScriptedNode) -> None:
    bench.armed()
    planner = bench.controller.planner
    target = SpeedPoint(20.0, 200.0)
    move = bench.controller.set_speeds(20.0, 200.0, rotary_rate_rpm_s=10.0, vibration_rate_rpm_s=50.0)
    assert move == planner.plan(STANDSTILL, target, 10.0, 50.0)  # by default the corridor, not the straight line
    assert move != planner.plan_linear(STANDSTILL, target, 10.0, 50.0)
    ramps = [segment.t1_s - segment.t0_s for segment in move.segments if segment.start != segment.end]
    assert ramps == pytest.approx([200.0 / 50.0, 20.0 / 10.0])  # each drive at its own rate asked
    assert bench.controller.trajectory is move
    bench.run(1.0, follow=True)
    sent = bench.messages(Setpoints)[-1]
    assert 0.0 < sent.vibration_rpm < 200.0 and sent.rotary_rpm == 0.0  # under way, vibration first, from rest


def test_a_linear_move_is_the_straight_line_at_the_rates_asked(bench: ScriptedNode) -> None:
    bench.armed()
    target = SpeedPoint(20.0, 200.0)
    move = bench.controller.set_speeds(20.0, 200.0, rotary_rate_rpm_s=10.0, vibration_rate_rpm_s=50.0, linear=True)
    assert move == bench.controller.planner.plan_linear(STANDSTILL, target, 10.0, 50.0)
    assert move.duration_s == pytest.approx(max(20.0 / 10.0, 200.0 / 50.0))


def test_a_move_is_recorded_with_who_asked_where_to_and_how_long(bench: ScriptedNode) -> None:
    bench.armed()
    move = bench.controller.set_speeds(20.0, 200.0, source=WHO)
    event = bench.last_event(EventKind.COMMAND)
    assert event.source == WHO
    assert event.time_s == bench.clock.now() > 0.0  # when, on the controller's clock
    assert event.data == {"rotary_rpm": 20.0, "vibration_rpm": 200.0, "duration_s": move.duration_s}
    assert event.message == f"ramp to ω_r = 20.0 rpm, ω_v = 200.0 rpm over {move.duration_s:.1f} s"
    bench.controller.set_speeds(20.0, 250.0)
    assert bench.last_event(EventKind.COMMAND).source == "operator"  # the default source


def test_a_refused_move_is_recorded_with_who_asked_and_what_and_changes_nothing(
    bench: ScriptedNode, config: MillConfig
) -> None:
    bench.armed()
    with pytest.raises(InterlockRefused) as refused:
        bench.controller.set_speeds(250.0, 800.0, source=WHO)
    event = bench.last_event(EventKind.REFUSAL)
    assert event.source == WHO
    assert event.message == str(refused.value)
    assert event.data == {"rotary_rpm": 250.0, "vibration_rpm": 800.0}
    assert bench.controller.trajectory is None and bench.controller.commanded == STANDSTILL
    too_fast = config.drives.rotary.max_accel_rpm_s * 2
    with pytest.raises(InterlockRefused):
        bench.controller.set_speeds(20.0, 200.0, rotary_rate_rpm_s=too_fast)
    with pytest.raises(InterlockRefused):
        bench.controller.set_speeds(20.0, 200.0, rotary_rate_rpm_s=too_fast, linear=True)
    assert bench.controller.trajectory is None


def test_speeds_with_a_furnace_target_start_both_at_the_heating_rate_asked(bench: ScriptedNode) -> None:
    bench.armed()
    bench.controller.set_speeds(20.0, 200.0, furnace_c=60.0, heating_rate_c_per_min=6.0, source=WHO)
    assert bench.controller.trajectory is not None
    assert (bench.controller.furnace_target_c, bench.controller.heating_rate_c_per_min) == (60.0, 6.0)
    furnace = bench.last_event(EventKind.COMMAND)
    assert furnace.source == WHO and furnace.data == {"temp_c": 60.0}
    bench.run(3.0, follow=True)
    sent = bench.messages(Setpoints)[-1]
    assert bench.controller.furnace_setpoint_c == pytest.approx(25.0 + 6.0 / 60.0 * 3.0)  # from 25 °C, 0.3 °C in 3 s
    assert sent.heater_on and sent.furnace_c == pytest.approx(25.3, abs=0.15)  # on the wire's 0.1 °C grid


def test_a_refused_furnace_part_leaves_the_speeds_untouched(bench: ScriptedNode, config: MillConfig) -> None:
    """Issue 15 item 7: the furnace part is checked, whole, before the speeds are planned or applied."""
    bench.armed()
    too_fast = config.furnace.max_heating_rate_c_per_min + 5.0
    sent_before = len(bench.of(Command))
    with pytest.raises(InterlockRefused, match=r"^furnace setpoint refused"):
        bench.controller.set_speeds(20.0, 200.0, furnace_c=60.0, heating_rate_c_per_min=too_fast, source=WHO)
    assert bench.last_event(EventKind.REFUSAL).source == WHO
    with pytest.raises(InterlockRefused, match=r"^furnace setpoint refused"):
        bench.controller.set_speeds(20.0, 200.0, furnace_c=config.furnace.max_setpoint_c + 50.0)
    assert bench.controller.trajectory is None and bench.controller.furnace_target_c is None
    bench.run(0.5, follow=True)
    assert {(s.rotary_rpm, s.vibration_rpm, s.heater_on) for s in bench.messages(Setpoints)} == {(0.0, 0.0, False)}
    assert len(bench.of(Command)) == sent_before


def test_a_refused_speed_part_leaves_the_furnace_untouched(bench: ScriptedNode) -> None:
    bench.armed()
    with pytest.raises(InterlockRefused):
        bench.controller.set_speeds(250.0, 800.0, furnace_c=60.0)
    assert bench.controller.furnace_target_c is None and bench.controller.trajectory is None


def test_a_heating_rate_without_a_furnace_target_is_refused_and_nothing_applies(bench: ScriptedNode) -> None:
    """A multi-part command is checked whole (SAFETY requirement 20): a heating rate with no target to heat to
    is not ignored but refused, naming the value and why, and neither the speeds nor the furnace change."""
    bench.armed()
    sent_before = len(bench.of(Command))
    with pytest.raises(InvalidInputError) as refused:
        bench.controller.set_speeds(20.0, 200.0, heating_rate_c_per_min=5.0, source=WHO)
    assert str(refused.value) == (
        "heating rate 5.0 °C/min given without a furnace target: there is nothing to heat to, and the rate "
        "would be ignored; give the target with it, or leave the rate out"
    )
    event = bench.last_event(EventKind.REFUSAL)
    assert (event.source, event.message, event.data) == (WHO, str(refused.value), {"heating_rate_c_per_min": 5.0})
    assert bench.controller.trajectory is None and bench.controller.furnace_target_c is None
    bench.run(0.5, follow=True)
    assert {(s.rotary_rpm, s.vibration_rpm, s.heater_on) for s in bench.messages(Setpoints)} == {(0.0, 0.0, False)}
    assert len(bench.of(Command)) == sent_before
    bench.controller.set_speeds(20.0, 200.0)  # without the rate: the speeds alone, the heater left off
    assert bench.controller.trajectory is not None and bench.controller.furnace_target_c is None


def test_a_heating_rate_with_the_heater_off_is_refused(bench: ScriptedNode) -> None:
    """``set_furnace(None)`` turns the heater off; a rate given with it would be ignored: refused instead,
    and the heater stays as it was."""
    bench.armed()
    bench.controller.set_furnace(60.0)
    with pytest.raises(InvalidInputError, match=r"^heating rate 5.0 °C/min given without a furnace target"):
        bench.controller.set_furnace(None, rate_c_per_min=5.0, source=WHO)
    assert bench.last_event(EventKind.REFUSAL).source == WHO
    assert bench.controller.furnace_target_c == 60.0


def test_a_move_set_late_in_a_run_starts_from_where_the_mill_is(bench: ScriptedNode) -> None:
    """Each setpoint is the plan at the time since the move began, however long the controller ran before: the
    first one sent is one setpoint period along the ramp, not part-way up it."""
    bench.armed()
    bench.run(2.0, state=NodeState.ARMED)  # the move begins 2.4 s after the controller started
    move = bench.controller.set_speeds(20.0, 200.0)
    began_s = bench.clock.now()
    bench.run(0.3, follow=True)
    snap = bench.controller.planner.snap
    sent = [(t, d.message) for t, d in bench.of(Setpoints) if t >= began_s]
    assert sent
    for t, setpoint in sent:
        planned = snap(move.at(t - began_s))
        assert isinstance(setpoint, Setpoints)
        assert (setpoint.rotary_rpm, setpoint.vibration_rpm) == (planned.omega_r_rpm, planned.omega_v_rpm)


def test_drives_that_lag_a_ramp_down_within_the_window_are_not_a_trip(bench: ScriptedNode) -> None:
    """The measured speeds may follow what was commanded up to one window late (interlock.command_confirm_s plus
    the drives' settle time): drives half a second behind a ramp down, above what is commanded now, are what the
    window is for."""
    bench.armed()
    up = bench.controller.set_speeds(20.0, 200.0)
    bench.run(up.duration_s + 0.5, follow=True)
    down = bench.controller.set_speeds(10.0, 100.0)
    lag_s = 0.5
    for i in range(round((down.duration_s + 1.0) / 0.01)):
        now = bench.clock.now()
        if i % 5 == 0:
            last = [d.message for t, d in bench.of(Setpoints) if t <= now - lag_s][-1]
            assert isinstance(last, Setpoints)
            bench.alive(NodeState.RUNNING, last.rotary_rpm, last.vibration_rpm)
        bench.controller.tick()
        bench.collect()
        bench.clock.advance(0.01)
    assert bench.controller.state is ControllerState.RUNNING, bench.controller.trip_cause
    assert bench.messages(Setpoints)[-1] == Setpoints(10.0, 100.0, 25.0, False)


def test_a_furnace_target_ramps_from_the_furnaces_measured_temperature(bench: ScriptedNode) -> None:
    """The setpoint starts where the furnace is (a warm furnace is not first cooled to ambient), then climbs at
    the heating rate; while the heater is on the setpoint ramps on from where it is."""
    bench.armed()
    bench.say(FurnaceTelemetry(140.0, 25.0, 0.0, False))  # still warm from an earlier run, heater off
    bench.run(0.05)
    bench.controller.set_furnace(300.0, rate_c_per_min=6.0, source=WHO)
    assert bench.controller.furnace_setpoint_c == 140.0
    event = bench.last_event(EventKind.COMMAND)
    assert (event.source, event.message, event.data) == (WHO, "furnace to 300.0 °C at 6.0 °C/min", {"temp_c": 300.0})
    bench.run(1.0, follow=True)
    heating = bench.controller.furnace_setpoint_c
    assert 140.0 < heating <= 140.0 + 6.0 / 60.0 * 1.0 + 1e-9  # climbing from there at no more than 0.1 °C/s
    bench.controller.set_furnace(200.0, rate_c_per_min=6.0)  # a new target while heating: no jump
    assert bench.controller.furnace_setpoint_c == heating


def test_a_furnace_target_before_any_furnace_report_ramps_from_ambient(config: MillConfig) -> None:
    """Armed on NodeStatus and DriveTelemetry alone (inside the furnace stream's start-up grace), the setpoint
    starts from the configured ambient temperature."""
    bench = ScriptedNode(config)
    try:
        for state in (NodeState.DISABLED, NodeState.ARMED):
            for _ in range(4):
                bench.say(NodeStatus(state))
                bench.say(DriveTelemetry(0.0, 0.0))
                bench.controller.tick()
                bench.clock.advance(0.05)
            if state is NodeState.DISABLED:
                bench.controller.arm()
        assert bench.controller.state is ControllerState.ARMED and bench.controller.furnace is None
        bench.controller.set_furnace(60.0)
        assert bench.controller.furnace_setpoint_c == config.furnace.ambient_temp_c
        assert bench.last_event(EventKind.COMMAND).source == "operator"  # the default source
        bench.controller.set_furnace(None)
        off = bench.last_event(EventKind.COMMAND)
        assert (off.source, off.message, bench.controller.furnace_target_c) == ("operator", "heater off", None)
    finally:
        bench.close()

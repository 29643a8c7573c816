"""Furnace targets confirmed apart from the speeds: the node's heater must follow what the controller commands.

docs/safety.md#believe-only-what-was-commanded. The scripted node reports FurnaceTelemetry with the heater
state and setpoint given, or (``follow``) those of the last Setpoints frame.
"""

from __future__ import annotations

from millctl.config import MillConfig
from millctl.controller import ControllerState
from millctl.controller.furnace_expect import FurnaceExpectation
from millctl.protocol import EStop, FurnaceTelemetry, NodeState, Setpoints
from tests.unit.controller.bench import ScriptedNode

S = ControllerState


def running(bench: ScriptedNode) -> None:
    bench.run(0.2, state=NodeState.DISABLED)
    bench.controller.arm()
    bench.run(0.2, state=NodeState.ARMED)
    move = bench.controller.set_speeds(60.0, 300.0)
    bench.run(move.duration_s + 0.5, follow=True)
    assert bench.controller.state is S.RUNNING, bench.controller.trip_cause


def heater_frames(bench: ScriptedNode) -> list[Setpoints]:
    return [d.message for _, d in bench.of(Setpoints) if isinstance(d.message, Setpoints) and d.message.heater_on]


def test_a_furnace_target_the_node_follows_up_and_down_never_trips(bench: ScriptedNode) -> None:
    running(bench)
    bench.controller.set_furnace(30.0)
    bench.run(17.0, follow=True)  # 5 °C at 20 °C/min: 15 s up, then held
    assert heater_frames(bench)[-1].furnace_c == 30.0
    bench.controller.set_furnace(28.0)
    bench.run(8.0, follow=True)  # and down at the same rate
    assert heater_frames(bench)[-1].furnace_c == 28.0
    bench.controller.set_furnace(None)
    bench.run(3.0, follow=True)
    assert bench.controller.state is S.RUNNING, bench.controller.trip_cause


def test_a_heater_the_node_turns_on_uncommanded_trips(bench: ScriptedNode, config: MillConfig) -> None:
    running(bench)
    bench.run(0.5, state=NodeState.RUNNING, rotary_rpm=60.0, vibration_rpm=300.0, setpoint_c=200.0, heater_on=True)
    assert bench.controller.state is S.TRIPPED
    cause = bench.controller.trip_cause
    assert "heater on at 200.0 °C" in cause and "(heater off over the last" in cause, cause
    assert f"{config.interlock.debounce_samples} reports in a row" in cause


def test_a_furnace_setpoint_above_the_one_commanded_trips(bench: ScriptedNode) -> None:
    running(bench)
    bench.controller.set_furnace(40.0)
    bench.run(3.0, follow=True)
    top = max(s.furnace_c for s in heater_frames(bench))
    assert bench.controller.state is S.RUNNING
    # within the wire's resolution of the highest setpoint commanded: believed
    bench.run(0.5, state=NodeState.RUNNING, rotary_rpm=60.0, vibration_rpm=300.0, setpoint_c=top + 0.1, heater_on=True)
    assert bench.controller.state is S.RUNNING, bench.controller.trip_cause
    bench.run(0.5, state=NodeState.RUNNING, rotary_rpm=60.0, vibration_rpm=300.0, setpoint_c=top + 5.0, heater_on=True)
    assert bench.controller.state is S.TRIPPED
    assert f"heater on at {top + 5.0:.1f} °C" in bench.controller.trip_cause


def test_a_node_one_wire_step_above_each_setpoint_it_was_sent_is_believed_all_along_a_ramp(
    bench: ScriptedNode,
) -> None:
    """The expectation holds what the Setpoints frames carry, on the wire's 0.1 °C grid, so a report within one
    grid step of it is believed at every point of a slow ramp, whichever way the setpoint was rounded."""
    running(bench)
    bench.controller.set_furnace(40.0, rate_c_per_min=6.0)  # 0.1 °C/s: each grid step takes 1 s
    for i in range(300):
        if i % 5 == 0:
            node = bench.followed()
            node["setpoint_c"] = float(node["setpoint_c"]) + 0.1  # type: ignore[arg-type]
            bench.alive(**node)  # type: ignore[arg-type]
        bench.controller.tick()
        bench.collect()
        bench.clock.advance(0.01)
    assert heater_frames(bench)[-1].furnace_c > 25.2  # the ramp went over several grid steps
    assert bench.controller.state is S.RUNNING, bench.controller.trip_cause


def test_a_furnace_target_the_node_does_not_take_trips_after_a_lag_window(bench: ScriptedNode) -> None:
    running(bench)
    bench.controller.set_furnace(40.0)
    window_s = bench.controller.furnace_expectation.window_s
    # the heater stays off: believed for the window in which it was not yet commanded throughout, and one more
    bench.run(2 * window_s - 0.2, state=NodeState.RUNNING, rotary_rpm=60.0, vibration_rpm=300.0)
    assert bench.controller.state is S.RUNNING, bench.controller.trip_cause
    bench.run(0.5, state=NodeState.RUNNING, rotary_rpm=60.0, vibration_rpm=300.0)
    assert bench.controller.state is S.TRIPPED
    cause = bench.controller.trip_cause
    assert cause.startswith("node reports heater off, which is not") and "did not take its furnace target" in cause


def test_a_setpoint_under_the_lowest_commanded_is_a_target_not_taken(bench: ScriptedNode) -> None:
    running(bench)
    bench.controller.set_furnace(40.0)
    bench.run(5.0, follow=True)
    bench.run(2.5, state=NodeState.RUNNING, rotary_rpm=60.0, vibration_rpm=300.0, setpoint_c=25.0, heater_on=True)
    assert bench.controller.state is S.TRIPPED
    assert "did not take its furnace target" in bench.controller.trip_cause


def test_a_heater_on_after_a_trip_is_an_estop(bench: ScriptedNode) -> None:
    running(bench)
    bench.run(0.2, state=NodeState.FAULT)
    assert bench.controller.state is S.TRIPPED
    estops = len(bench.of(EStop))
    bench.run(1.5, state=NodeState.FAULT, setpoint_c=300.0, heater_on=True)
    assert len(bench.of(EStop)) > estops
    assert any("heater on at 300.0 °C" in e.message for e in bench.events)


def test_a_heater_commanded_off_in_part_of_the_window_bounds_only_from_above() -> None:
    expect = FurnaceExpectation(window_s=1.0, debounce_samples=1)
    for k in range(10):
        expect.commanded(k * 0.1, None)
    for k in range(10, 20):
        expect.commanded(k * 0.1, 50.0)
    off = FurnaceTelemetry(25.0, 25.0, 0.0, False)
    assert expect.check(1.9, off) is None  # not commanded on for a whole window yet
    assert expect.check(1.9, FurnaceTelemetry(25.0, 50.0, 10.0, True)) is None
    reason = expect.check(1.9, FurnaceTelemetry(25.0, 50.2, 10.0, True))
    assert reason is not None and "(heater off or on at up to 50.0 °C over the last 1.0 s" in reason
    expect.reset()
    for k in range(20, 31):
        expect.commanded(k * 0.1, 50.0)
    assert expect.check(3.0, off) is None  # below: counts from now
    assert expect.check(3.99, off) is None
    reason = expect.check(4.0, off)
    assert reason is not None and "heater on at 50.0…50.0 °C" in reason and "below it for 1.0 s" in reason


def test_nothing_is_judged_before_anything_was_commanded() -> None:
    expect = FurnaceExpectation(window_s=1.0, debounce_samples=1)
    assert expect.check(0.0, FurnaceTelemetry(25.0, 500.0, 100.0, True)) is None


def test_heat_nobody_commanded_counts_from_the_first_report_and_again_after_a_reset() -> None:
    expect = FurnaceExpectation(window_s=1.0, debounce_samples=3)
    expect.commanded(0.0, None)
    on = FurnaceTelemetry(25.0, 80.0, 50.0, True)
    for _ in range(2):
        assert expect.check(0.1, on) is None and expect.check(0.2, on) is None
        assert expect.check(0.3, on) is not None
        expect.reset()


def test_a_target_not_taken_counts_from_the_first_report_of_a_fresh_expectation() -> None:
    expect = FurnaceExpectation(window_s=1.0, debounce_samples=3)
    for k in range(11):
        expect.commanded(k * 0.1, 50.0)
    off = FurnaceTelemetry(25.0, 25.0, 0.0, False)
    assert expect.check(1.0, off) is None
    expect.commanded(2.0, 50.0)
    assert expect.check(2.0, off) is not None


def test_a_target_commanded_for_less_than_a_window_is_not_yet_expected() -> None:
    expect = FurnaceExpectation(window_s=1.0, debounce_samples=3)
    off = FurnaceTelemetry(25.0, 25.0, 0.0, False)
    for k in range(16):
        expect.commanded(k * 0.1, 50.0)
        assert expect.check(k * 0.1, off) is None  # on throughout only from t = 1.0: below counts from there


def test_the_latest_target_at_an_instant_replaces_the_earlier() -> None:
    expect = FurnaceExpectation(window_s=1.0, debounce_samples=1)
    expect.commanded(0.0, None)
    expect.commanded(1.0, 80.0)
    expect.commanded(1.0, 50.0)  # revised within the same tick: 80 °C was never sent
    assert expect.check(1.0, FurnaceTelemetry(25.0, 80.0, 50.0, True)) is not None

"""Setpoint interlock on the node (SAFETY.md items 4 and 12, node side): refused, never clamped."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from millctl.config import MillConfig
from millctl.protocol import NodeState, NodeStatus, RefusalCode, Setpoints

from .conftest import Bench


def _refused(bench: Bench, setpoint: Setpoints) -> RefusalCode:
    before = bench.node.refused_setpoints
    bench.send(setpoint)
    bench.step(bench.tick_s)
    assert bench.node.refused_setpoints == before + 1
    return bench.node.last_refusal


def test_safety_4_setpoint_outside_the_envelope_is_refused_not_clamped(bench: Bench) -> None:
    bench.run_at(100.0, 300.0)
    limit_rpm = float(bench.envelope.omega_r_limit_rpm(300.0))
    accepted = bench.node.last_setpoint
    assert _refused(bench, Setpoints(round(limit_rpm + 2.0, 1), 300.0, 25.0, False)) is RefusalCode.ENVELOPE
    assert bench.node.last_setpoint == accepted
    bench.step(1.0)
    assert bench.node.true_speeds_rpm[0] < 100.0 + 2.0
    bench.step(0.06)
    assert bench.latest(NodeStatus).last_refusal is RefusalCode.ENVELOPE


def test_safety_4_absolute_speed_and_temperature_limits(bench: Bench) -> None:
    bench.arm()
    too_fast = bench.config.drives.vibration.max_speed_rpm + 10.0
    assert _refused(bench, Setpoints(0.0, too_fast, 25.0, False)) is RefusalCode.SPEED_LIMIT
    too_hot = bench.config.furnace.max_setpoint_c + 10.0
    assert _refused(bench, Setpoints(0.0, 0.0, too_hot, True)) is RefusalCode.TEMP_LIMIT
    assert not bench.node.heater_on
    assert bench.node.state is NodeState.ARMED


def test_safety_4_a_rotor_over_its_drives_maximum_is_refused_speed_limit_where_the_law_allows_more(
    make_bench: Callable[..., Bench], config: MillConfig
) -> None:
    """Where the drive's own maximum is below the law's limit, exceeding it is SPEED_LIMIT, not ENVELOPE."""
    rotary = config.drives.rotary.model_copy(update={"max_speed_rpm": 150.0})
    cfg = config.model_copy(update={"drives": config.drives.model_copy(update={"rotary": rotary})})
    bench: Bench = make_bench(cfg)
    assert float(bench.envelope.omega_r_limit_rpm(800.0)) == 150.0  # the law alone would allow ≈ 190 rpm
    bench.run_at(140.0, 800.0)
    assert _refused(bench, Setpoints(155.0, 800.0, 25.0, False)) is RefusalCode.SPEED_LIMIT


def test_safety_12_a_raw_jump_is_refused_accel_limit(bench: Bench) -> None:
    bench.arm()
    target = Setpoints(180.0, 800.0, 25.0, False)
    assert bench.envelope.check(180.0, 800.0).ok
    assert _refused(bench, target) is RefusalCode.ACCEL_LIMIT
    bench.step(2.0)
    assert _refused(bench, target) is RefusalCode.ACCEL_LIMIT  # waiting does not bank a large step
    assert bench.node.true_speeds_rpm == (0.0, 0.0)
    assert bench.node.state is NodeState.ARMED


def test_safety_12_a_fast_forger_cannot_walk_the_setpoint_faster_than_the_drives_rate(bench: Bench) -> None:
    """A 100 Hz sender asking for 5 rpm of ω_v a frame (the old per-frame step limit allowed 18.2 rpm each, 1820
    rpm/s): over any window the node accepts at most 1.5 × max accel × the window + its burst."""
    bench.arm()
    accel = bench.config.drives.vibration.max_accel_rpm_s
    burst = 1.5 * accel * bench.config.timing.watchdog_timeout_s + 0.2
    frame_s, asked = 0.01, 0.0
    accepted: list[tuple[float, float]] = []  # (time, accepted ω_v)
    refusals: set[RefusalCode] = set()
    for _ in range(100):  # one second
        asked += 5.0
        before = bench.node.refused_setpoints
        bench.send(Setpoints(0.0, asked, 25.0, False))
        bench.step(frame_s, dt_s=frame_s)
        now_rpm = bench.node.last_setpoint.vibration_rpm if bench.node.last_setpoint else 0.0
        if bench.node.refused_setpoints != before:
            refusals.add(bench.node.last_refusal)
            asked = now_rpm
        accepted.append((bench.clock.now(), now_rpm))
    assert refusals == {RefusalCode.ACCEL_LIMIT}
    for i, (t1, v1) in enumerate(accepted):
        for t2, v2 in accepted[i + 1 :]:
            assert v2 - v1 <= burst + 1.5 * accel * (t2 - t1) + 1e-6, f"{v2 - v1:.1f} rpm in {t2 - t1:.2f} s"
    # the slowest honest sender (one frame per setpoint period) gets as far as the fast one
    assert accepted[-1][1] >= 1.5 * accel * 0.9


def test_safety_12_the_largest_single_step_is_the_burst(bench: Bench) -> None:
    """From rest, one frame may step a drive by 1.5 × max accel × watchdog_timeout_s + 0.2 rpm, not 0.1 rpm more."""
    bench.arm()
    burst = 1.5 * bench.config.drives.vibration.max_accel_rpm_s * bench.config.timing.watchdog_timeout_s + 0.2
    assert _refused(bench, Setpoints(0.0, round(burst + 0.1, 1), 25.0, False)) is RefusalCode.ACCEL_LIMIT
    bench.send(Setpoints(0.0, round(burst, 1), 25.0, False))
    bench.step(bench.tick_s)
    assert bench.node.last_setpoint == Setpoints(0.0, round(burst, 1), 25.0, False)


def test_a_heater_off_frame_is_not_judged_by_its_unused_furnace_setpoint(bench: Bench) -> None:
    bench.arm()
    unused_c = bench.config.furnace.max_setpoint_c + 100.0
    bench.send(Setpoints(0.0, 10.0, unused_c, False))
    bench.step(bench.tick_s)
    assert bench.node.refused_setpoints == 0
    assert bench.node.last_setpoint == Setpoints(0.0, 10.0, unused_c, False)
    assert not bench.node.heater_on


def test_safety_12_the_controllers_sampled_ramp_passes(bench: Bench) -> None:
    bench.run_at(180.0, 800.0)
    assert bench.node.refused_setpoints == 0
    m_r, m_v = bench.node.measured_speeds_rpm
    assert abs(m_r - 180.0) < 3.0 and abs(m_v - 800.0) < 5.0


def test_refused_setpoints_in_stopping_and_fault(bench: Bench) -> None:
    from millctl.protocol import CommandCode

    bench.run_at(50.0, 200.0)
    bench.command(CommandCode.STOP)
    bench.step(0.02)
    assert _refused(bench, Setpoints(50.0, 200.0, 25.0, False)) is RefusalCode.WRONG_STATE
    bench.step(0.4, heartbeat=False)
    assert bench.node.state is NodeState.FAULT
    assert _refused(bench, Setpoints(0.0, 0.0, 25.0, False)) is RefusalCode.FAULT_LATCHED


_moves = st.lists(
    st.one_of(
        st.tuples(st.just("rel"), st.floats(-25.0, 25.0), st.floats(-80.0, 80.0), st.integers(1, 10)),
        st.tuples(st.just("edge"), st.floats(0.8, 1.1), st.floats(0.0, 1300.0), st.integers(1, 60)),
    ),
    min_size=3,
    max_size=10,
)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(moves=_moves, seed=st.integers(0, 2**16))
@example(moves=[("edge", 0.95, 800.0, 100), ("rel", 0.0, 0.0, 1)], seed=0)
def test_safety_12_raw_sender_cannot_drive_the_node_outside_the_envelope(
    config: MillConfig, moves: list[tuple[str, float, float, int]], seed: int
) -> None:
    bench = Bench(config, seed=seed)
    tolerance = bench.envelope.measurement_tolerance_rpm
    worst: list[float] = []

    def watch(b: Bench) -> None:
        m_r, m_v = b.node.measured_speeds_rpm
        if not b.envelope.contains(m_r, m_v, tolerance):
            worst.append(m_r - float(b.envelope.omega_r_limit_rpm(m_v)))

    try:
        bench.arm()
        bench.on_tick.append(watch)
        r, v = 0.0, 0.0
        for mode, a, b, wait in moves:
            # "rel": a step from the last accepted setpoint; "edge": a fraction a of the limit at ω_v = b.
            r, v = (r + a, v + b) if mode == "rel" else (a * float(bench.envelope.omega_r_limit_rpm(b)), b)
            r, v = float(np.clip(r, 0.0, 2000.0)), float(np.clip(v, 0.0, 2000.0))
            bench.setpoints(r, v)
            bench.step(wait * 0.04, dt_s=0.04)
            accepted = bench.node.last_setpoint
            if accepted is not None:
                r, v = accepted.rotary_rpm, accepted.vibration_rpm
        bench.step(4.0, dt_s=0.04)
        assert worst == []
        assert bench.node.state in (NodeState.ARMED, NodeState.RUNNING)
    finally:
        bench.close()

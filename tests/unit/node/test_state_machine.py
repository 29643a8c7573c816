"""The node's state machine and link safety (SAFETY.md items 1, 2, 3, 8, 9, 10 — node side)."""

from __future__ import annotations

import math

import can

from millctl.protocol import (
    Command,
    CommandCode,
    ControllerState,
    DriveTelemetry,
    FaultCode,
    FaultFlag,
    FurnaceTelemetry,
    Heartbeat,
    NodeState,
    NodeStatus,
    RefusalCode,
    Setpoints,
)

from .conftest import Bench


def test_safety_1_boots_disabled_speeds_zero_heater_off(bench: Bench) -> None:
    node = bench.node
    bench.step(0.5)
    assert node.state is NodeState.DISABLED
    assert node.true_speeds_rpm == (0.0, 0.0)
    assert not node.heater_on
    status = bench.latest(NodeStatus)
    assert status.state is NodeState.DISABLED and status.fault_bits == 0
    bench.setpoints(10.0, 30.0)
    bench.step(0.05)
    assert node.last_refusal is RefusalCode.NOT_ARMED
    assert node.last_setpoint is None
    assert node.true_speeds_rpm == (0.0, 0.0)


def test_safety_1_arm_needs_a_live_heartbeat(bench: Bench) -> None:
    node = bench.node
    bench.step(0.1, heartbeat=False)
    bench.command(CommandCode.ARM)
    bench.step(0.01, heartbeat=False)
    assert node.state is NodeState.DISABLED
    assert node.last_refusal is RefusalCode.NOT_FRESH
    bench.arm()
    assert node.state is NodeState.ARMED


def test_running_and_back_to_armed_and_disarm(bench: Bench) -> None:
    node = bench.node
    bench.run_at(50.0, 200.0)
    assert node.state is NodeState.RUNNING
    bench.command(CommandCode.DISARM)
    bench.step(0.02)
    assert node.state is NodeState.RUNNING and node.last_refusal is RefusalCode.WRONG_STATE
    bench.ramp_to(0.0, 0.0)
    bench.step(0.5)
    assert node.state is NodeState.ARMED
    bench.command(CommandCode.DISARM)
    bench.step(0.02)
    assert node.state is NodeState.DISABLED


def test_stop_command_plans_a_controlled_stop_inside_the_envelope(bench: Bench) -> None:
    node = bench.node
    bench.run_at(120.0, 400.0)
    bench.hold = Setpoints(30.0, 300.0, 25.0, True)
    bench.command(CommandCode.STOP)
    bench.hold = None
    outside: list[tuple[float, float]] = []
    bench.on_tick.append(
        lambda b: (
            outside.append(b.node.measured_speeds_rpm)
            if not b.envelope.check_measured(*b.node.measured_speeds_rpm).ok
            else None
        )
    )
    bench.step(0.02)
    assert node.state is NodeState.STOPPING
    assert not node.heater_on
    bench.step(8.0)
    assert node.state is NodeState.ARMED
    assert max(node.true_speeds_rpm) <= bench.envelope.measurement_tolerance_rpm
    assert outside == []


def test_the_nodes_stop_slows_the_rotor_at_its_drives_rate_then_vibration_once_the_rotor_has_settled(
    bench: Bench,
) -> None:
    """Stop category 1: the rotor is ramped down at its maximum deceleration, not dropped; ω_v is lowered only
    after a dwell of 3 time constants, when the rotor has followed its ramp to rest (docs/operations.md)."""
    rotary = bench.config.drives.rotary
    bench.run_at(180.0, 800.0)
    bench.command(CommandCode.STOP)
    samples: list[tuple[float, tuple[float, float]]] = []
    bench.on_tick.append(lambda b: samples.append((b.clock.now(), b.node.true_speeds_rpm)))
    bench.step(14.0)  # 4.5 s of ω_r, 0.6 s of dwell, 6.7 s of ω_v
    t0 = samples[0][0]
    for t, (r, _) in samples:
        assert r >= 180.0 - 1.1 * rotary.max_accel_rpm_s * (t - t0) - 2.0, f"ω_r = {r:.1f} rpm {t - t0:.2f} s in"
    lag_rpm = rotary.max_accel_rpm_s * rotary.time_constant_s  # the rotor's lag behind its ramp
    r_when_v_falls = next(r for _, (r, v) in samples if v < 799.0)
    assert r_when_v_falls <= lag_rpm * math.exp(-2.0)
    assert bench.node.state is NodeState.ARMED


def test_safety_2_watchdog_trips_within_one_tick_and_stops_inside_the_envelope(bench: Bench) -> None:
    node = bench.node
    bench.run_at(145.0, 400.0)
    bench.heartbeat()
    last_heartbeat_s = bench.clock.now() + bench.tick_s  # received at the next tick
    tripped_at: list[float] = []
    worst_margin: list[float] = []

    def watch(b: Bench) -> None:
        if not tripped_at and node.state is NodeState.FAULT:
            tripped_at.append(b.clock.now())
        m_r, m_v = node.measured_speeds_rpm
        if m_r > b.envelope.measurement_tolerance_rpm:
            worst_margin.append(float(b.envelope.omega_r_limit_rpm(m_v)) - m_r)

    bench.on_tick.append(watch)
    bench.step(9.0, heartbeat=False)
    timeout_s = bench.config.timing.watchdog_timeout_s
    assert tripped_at and tripped_at[0] - last_heartbeat_s <= timeout_s + bench.tick_s + 1e-9
    assert node.first_fault is FaultCode.WATCHDOG
    assert FaultFlag.WATCHDOG in node.fault_bits
    assert not node.heater_on
    assert node.true_speeds_rpm == (0.0, 0.0)
    assert min(worst_margin) >= -bench.envelope.measurement_tolerance_rpm


def test_watchdog_fed_at_0_7_timeout_never_trips(bench: Bench) -> None:
    bench.heartbeat_period_s = 0.7 * bench.config.timing.watchdog_timeout_s
    bench.run_at(40.0, 150.0)
    bench.step(20.0, dt_s=bench.heartbeat_period_s / 7.0)
    assert bench.node.state is NodeState.RUNNING
    assert bench.node.fault_bits == 0


def test_watchdog_trips_by_timeout_plus_one_tick_when_fed_no_more(bench: Bench) -> None:
    bench.arm()
    bench.heartbeat()
    fed_at = bench.clock.now()
    timeout_s = bench.config.timing.watchdog_timeout_s
    tick_s = bench.config.timing.node_tick_s
    ticks_allowed = math.ceil((timeout_s + tick_s) / tick_s) + 1  # bounded: a watchdog that never trips fails here
    for _ in range(ticks_allowed):
        if bench.node.state is not NodeState.ARMED:
            break
        bench.step(tick_s, heartbeat=False, dt_s=tick_s)
    assert bench.node.state is not NodeState.ARMED, f"still ARMED {ticks_allowed} ticks after the last heartbeat"
    assert bench.clock.now() - fed_at <= timeout_s + tick_s + 1e-9
    assert bench.clock.now() - fed_at > timeout_s - 1e-9
    assert bench.node.first_fault is FaultCode.WATCHDOG


def test_safety_2_repeated_heartbeat_counter_never_feeds_the_watchdog(bench: Bench) -> None:
    bench.arm()
    frozen = bench.counters[Heartbeat].next()
    for _ in range(4):  # the first is fresh, the repeats are not: fewer than the E2E error limit
        bench.send(Heartbeat(ControllerState.RUNNING), counter=frozen)
        bench.step(0.1, heartbeat=False)
    assert bench.node.state is NodeState.FAULT
    assert bench.node.first_fault is FaultCode.WATCHDOG


def test_safety_3_bad_crc_is_discarded_and_persistent_errors_fault_the_link(bench: Bench) -> None:
    node = bench.node
    bench.arm()
    frame = bench.codec.encode(Setpoints(20.0, 100.0, 25.0, False), bench.counters[Setpoints].next())
    data = bytearray(frame.data)
    data[2] ^= 0x40
    bench.ctl_bus.send(can.Message(arbitration_id=frame.arbitration_id, data=bytes(data), is_extended_id=False))
    bench.step(0.02)
    assert node.last_refusal is RefusalCode.E2E
    assert node.last_setpoint is None
    assert node.state is NodeState.ARMED
    for _ in range(bench.config.interlock.e2e_error_limit):
        bench.ctl_bus.send(can.Message(arbitration_id=frame.arbitration_id, data=bytes(data), is_extended_id=False))
    bench.step(0.02)
    assert node.state is NodeState.FAULT
    assert node.first_fault is FaultCode.E2E_LINK


def test_a_command_with_a_bad_crc_is_refused_as_e2e_and_not_acted_on(bench: Bench) -> None:
    node = bench.node
    bench.arm()
    frame = bench.codec.encode(Command(CommandCode.DISARM), bench.counters[Command].next())
    data = bytearray(frame.data)
    data[-1] ^= 0x01  # the CRC byte: it no longer matches the data
    bench.ctl_bus.send(can.Message(arbitration_id=frame.arbitration_id, data=bytes(data), is_extended_id=False))
    bench.step(0.1)
    assert node.last_refusal is RefusalCode.E2E
    assert node.state is NodeState.ARMED  # the DISARM was not taken
    assert bench.latest(NodeStatus).last_refusal is RefusalCode.E2E  # and the node says why


def test_a_frame_that_does_not_decode_is_counted_named_and_the_node_goes_on(bench: Bench) -> None:
    node = bench.node
    bench.arm()
    command_id = bench.codec.encode(Command(CommandCode.DISARM), 0).arbitration_id
    bench.ctl_bus.send(can.Message(arbitration_id=command_id, data=b"\x01", is_extended_id=False))  # 1 byte
    bench.step(0.1)
    assert node.reader.counts.malformed == 1
    assert f"0x{command_id:03X}" in node.reader.counts.last_error
    assert node.state is NodeState.ARMED
    bench.command(CommandCode.DISARM)  # the frames after it are still taken
    bench.step(0.1)
    assert node.state is NodeState.DISABLED


def test_safety_8_fault_latches_and_reset_needs_standstill_fresh_and_causes_cleared(bench: Bench) -> None:
    node = bench.node
    bench.run_at(60.0, 300.0)
    bench.hold = None
    bench.step(0.4, heartbeat=False)
    assert node.state is NodeState.FAULT and node.first_fault is FaultCode.WATCHDOG
    bench.command(CommandCode.RESET)
    bench.step(0.02, heartbeat=False)
    assert node.state is NodeState.FAULT
    assert node.last_refusal is RefusalCode.NOT_STANDSTILL
    bench.step(6.0, heartbeat=False)
    assert node.true_speeds_rpm == (0.0, 0.0)
    bench.command(CommandCode.RESET)
    bench.step(0.02, heartbeat=False)
    assert node.state is NodeState.FAULT
    assert node.last_refusal is RefusalCode.FAULT_LATCHED  # the heartbeat is still missing
    bench.step(0.2)
    bench.command(CommandCode.RESET)
    bench.step(0.02)
    assert node.state is NodeState.DISABLED
    assert node.fault_bits == 0 and node.first_fault is FaultCode.NONE
    bench.setpoints(10.0, 50.0)
    bench.step(0.5)
    assert node.last_refusal is RefusalCode.NOT_ARMED
    assert node.true_speeds_rpm == (0.0, 0.0)


def test_safety_8_reset_with_a_repeated_counter_is_refused(bench: Bench) -> None:
    node = bench.node
    bench.arm()
    bench.step(0.4, heartbeat=False)
    assert node.state is NodeState.FAULT
    bench.step(0.3)
    counter = bench.counters[Command].value - 1
    bench.send(Command(CommandCode.RESET), counter=counter)
    bench.step(0.02)
    assert node.state is NodeState.FAULT
    assert node.last_refusal is RefusalCode.NOT_FRESH


def test_safety_8_reset_is_refused_outside_fault(bench: Bench) -> None:
    bench.arm()
    bench.command(CommandCode.RESET)
    bench.step(0.02)
    assert bench.node.state is NodeState.ARMED
    assert bench.node.last_refusal is RefusalCode.WRONG_STATE


def test_safety_9_node_broadcasts_state_fault_bits_and_first_fault(bench: Bench) -> None:
    bench.arm()
    bench.step(0.4, heartbeat=False)
    bench.ctl_bus.send(can.Message(arbitration_id=0x000, data=b"", is_extended_id=False))
    bench.step(0.2, heartbeat=False)
    status = bench.latest(NodeStatus)
    assert status.state is NodeState.FAULT
    assert status.first_fault is FaultCode.WATCHDOG
    assert FaultFlag.WATCHDOG in status.fault_bits and FaultFlag.ESTOP in status.fault_bits
    assert isinstance(bench.latest(DriveTelemetry), DriveTelemetry)
    assert isinstance(bench.latest(FurnaceTelemetry), FurnaceTelemetry)


def test_safety_10_estop_from_any_sender_with_any_content(bench: Bench) -> None:
    node = bench.node
    bench.run_at(120.0, 300.0)
    bench.hold = Setpoints(120.0, 300.0, 200.0, True)
    bench.step(0.3)
    stranger = can.Bus(interface="virtual", channel=bench.channel, receive_own_messages=False)
    try:
        stranger.send(can.Message(arbitration_id=0x000, data=b"\xff\x01\x02", is_extended_id=False))
    finally:
        stranger.shutdown()
    bench.step(bench.tick_s)
    assert node.state is NodeState.FAULT
    assert node.first_fault is FaultCode.ESTOP
    assert not node.heater_on
    rotary_rpm = node.true_speeds_rpm[0]
    bench.step(1.0)
    # ω_r first, at the drive's maximum deceleration (40 rpm/s here): well down after 1 s.
    assert node.true_speeds_rpm[0] < rotary_rpm - 0.6 * bench.config.drives.rotary.max_accel_rpm_s
    bench.step(7.0)
    assert node.true_speeds_rpm == (0.0, 0.0)


def test_safety_10_estop_is_handled_before_other_frames_of_the_same_tick(bench: Bench) -> None:
    bench.arm()
    bench.setpoints(5.0, 20.0)
    bench.ctl_bus.send(can.Message(arbitration_id=0x000, data=bytes(8), is_extended_id=False))
    bench.step(bench.tick_s)
    assert bench.node.first_fault is FaultCode.ESTOP
    assert bench.node.last_setpoint is None
    assert bench.node.last_refusal is RefusalCode.FAULT_LATCHED


def test_safety_2_heartbeats_with_some_lost_still_feed_the_watchdog(bench: Bench) -> None:
    bench.arm()
    for _ in range(30):  # every other heartbeat lost: the counter advances by 2 (OK_SOME_LOST)
        bench.counters[Heartbeat].next()
        bench.heartbeat()
        bench.step(0.1, heartbeat=False)
    assert bench.node.state is NodeState.ARMED
    assert bench.node.fault_bits == 0

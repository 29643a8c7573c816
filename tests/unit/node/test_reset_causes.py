"""What the node's RESET, RUNNING and shutdown rules need, each shown at its edge (firmware_sim/node.py).

RESET clears a latched fault only at standstill and only when none of its
causes is still there: an E2E link whose score is still at the limit, a
furnace still over its over-temperature (SAFETY.md item 8). A node is
RUNNING from the first accepted setpoint that turns either drive, and stays
RUNNING until both drives are at rest; a process that ends stops the mill.
"""

from __future__ import annotations

from collections.abc import Callable

import can

from firmware_sim.node import _lowest
from millctl.config import MillConfig
from millctl.protocol import (
    CommandCode,
    FaultCode,
    FaultFlag,
    NodeState,
    NodeStatus,
    RefusalCode,
    Setpoints,
    SimFaultCode,
)

from .conftest import Bench


def state(bench: Bench) -> NodeState:
    """The node's state now (a call, so that mypy does not carry an earlier assertion's narrowing over)."""
    return bench.node.state


def corrupt_setpoints(bench: Bench) -> can.Message:
    """A Setpoints frame whose CRC does not match its data (what a disturbed bus delivers)."""
    frame = bench.codec.encode(Setpoints(0.0, 0.0, 25.0, False), bench.counters[Setpoints].next())
    data = bytearray(frame.data)
    data[2] ^= 0x40
    return can.Message(arbitration_id=frame.arbitration_id, data=bytes(data), is_extended_id=False)


def test_reset_is_refused_while_the_e2e_link_is_still_faulted_and_taken_once_good_frames_clear_it(
    bench: Bench,
) -> None:
    node = bench.node
    bench.arm()
    for _ in range(bench.config.interlock.e2e_error_limit):
        bench.ctl_bus.send(corrupt_setpoints(bench))
    bench.step(0.1)
    assert state(bench) is NodeState.FAULT and node.first_fault is FaultCode.E2E_LINK
    assert node.link.faulted
    bench.command(CommandCode.RESET)
    bench.step(0.02)
    assert state(bench) is NodeState.FAULT
    assert node.last_refusal is RefusalCode.FAULT_LATCHED  # the cause is still there
    for _ in range(bench.config.interlock.e2e_error_limit):  # good frames bring the score down (refused in FAULT)
        bench.setpoints(0.0, 0.0)
    bench.step(0.02)
    assert not node.link.faulted
    bench.command(CommandCode.RESET)
    bench.step(0.02)
    assert state(bench) is NodeState.DISABLED
    assert node.fault_bits == 0


def test_reset_is_refused_while_the_furnace_is_still_over_temperature_and_taken_once_it_has_cooled(
    config: MillConfig, make_bench: Callable[..., Bench]
) -> None:
    small = config.model_copy(update={"furnace": config.furnace.model_copy(update={"heat_capacity_j_per_k": 50.0})})
    bench = make_bench(small, fault_injection=True)
    node = bench.node
    over_c = small.furnace.over_temp_c
    bench.step(0.05)
    bench.inject(SimFaultCode.HEATER_FAIL, 1.0)  # welded relay: full power whatever the node says
    bench.step(100.0, dt_s=0.5)
    assert state(bench) is NodeState.FAULT and FaultFlag.OVERTEMP in node.fault_bits
    bench.inject(SimFaultCode.HEATER_FAIL, active=False)  # the relay is mended; the furnace is still hot
    bench.step(0.05)
    assert node.furnace_temp_c >= over_c
    bench.command(CommandCode.RESET)
    bench.step(0.02)
    assert state(bench) is NodeState.FAULT
    assert node.last_refusal is RefusalCode.FAULT_LATCHED
    for _ in range(400):  # let it cool below the over-temperature
        bench.step(0.5, dt_s=0.5)
        if node.furnace_temp_c < over_c:
            break
    assert node.furnace_temp_c < over_c
    bench.command(CommandCode.RESET)
    bench.step(0.02)
    assert state(bench) is NodeState.DISABLED


def test_a_setpoints_frame_with_a_repeated_counter_is_refused_and_not_applied(bench: Bench) -> None:
    node = bench.node
    bench.arm()
    bench.setpoints(0.0, 0.0)
    bench.step(0.02)
    assert node.last_setpoint == Setpoints(0.0, 0.0, 25.0, False)
    replay = bench.counters[Setpoints].value - 1
    bench.send(Setpoints(1.0, 5.0, 25.0, False), counter=replay)  # a good CRC, a stale counter
    bench.step(0.02)
    assert node.last_refusal is RefusalCode.E2E
    assert node.last_setpoint == Setpoints(0.0, 0.0, 25.0, False)
    assert state(bench) is NodeState.ARMED


def test_a_setpoint_that_turns_either_drive_however_little_makes_the_node_running(
    make_bench: Callable[..., Bench],
) -> None:
    for rotary_rpm, vibration_rpm in ((0.0, 5.0), (0.5, 0.0), (0.0, 0.5)):
        bench = make_bench()
        bench.arm()
        assert state(bench) is NodeState.ARMED
        bench.setpoints(rotary_rpm, vibration_rpm)
        bench.step(bench.tick_s)
        assert state(bench) is NodeState.RUNNING, (rotary_rpm, vibration_rpm)


def test_the_node_stays_running_until_its_drives_are_at_rest_after_zero_setpoints(bench: Bench) -> None:
    node = bench.node
    tolerance_rpm = bench.config.interlock.measurement_tolerance_rpm
    bench.run_at(0.0, 20.0)
    assert state(bench) is NodeState.RUNNING
    bench.ramp_to(0.0, 0.0)  # ends with zero setpoints, then settles
    assert state(bench) is NodeState.ARMED
    bench.run_at(0.0, 20.0)
    bench.hold = Setpoints(0.0, 10.0, 25.0, False)
    bench.step(1.0)
    bench.hold = Setpoints(0.0, 0.0, 25.0, False)
    bench.setpoints(0.0, 0.0)  # zero at once (within the burst): accepted, and the drive still turns
    bench.step(bench.tick_s)
    assert node.last_setpoint == Setpoints(0.0, 0.0, 25.0, False)
    assert max(node.measured_speeds_rpm) > tolerance_rpm
    assert state(bench) is NodeState.RUNNING
    bench.step(5.0)
    assert state(bench) is NodeState.ARMED


def test_a_process_that_ends_stops_a_running_mill_with_the_heater_off(bench: Bench) -> None:
    node = bench.node
    bench.run_at(40.0, 150.0)
    node.shutdown_stop()
    assert state(bench) is NodeState.STOPPING
    assert not node.heater_on
    bench.hold = None
    bench.step(6.0)
    assert node.true_speeds_rpm == (0.0, 0.0)


def test_a_process_that_ends_in_fault_still_brings_the_drives_to_rest(bench: Bench) -> None:
    node = bench.node
    bench.run_at(40.0, 150.0)
    bench.hold = None
    bench.step(0.4, heartbeat=False)  # watchdog: FAULT, its own stop under way
    assert state(bench) is NodeState.FAULT
    node.shutdown_stop()
    assert state(bench) is NodeState.FAULT
    assert not node.heater_on
    bench.step(6.0, heartbeat=False)
    assert node.true_speeds_rpm == (0.0, 0.0)


def test_the_first_fault_of_several_latched_together_is_the_lowest_bit() -> None:
    both = FaultFlag.WATCHDOG | FaultFlag.E2E_LINK
    lowest = min(FaultFlag.WATCHDOG, FaultFlag.E2E_LINK, key=int)
    assert _lowest(both) is lowest
    assert _lowest(FaultFlag.ESTOP) is FaultFlag.ESTOP


def test_causes_that_fire_in_the_same_tick_are_all_latched_and_each_is_checked_at_reset(
    config: MillConfig, make_bench: Callable[..., Bench]
) -> None:
    """Four causes in one tick: the furnace over its over-temperature, the watchdog expired, the E2E link
    faulted and the heater setpoint not refreshed. Each is latched and reported (none overwrites another), and
    RESET still finds the ones that are present (docs/safety.md#mutation-testing: `_checks`)."""
    small = config.model_copy(update={"furnace": config.furnace.model_copy(update={"heat_capacity_j_per_k": 50.0})})
    bench = make_bench(small, fault_injection=True)
    node = bench.node
    bench.arm()
    bench.setpoints(0.0, 0.0, furnace_c=100.0, heater=True)
    bench.inject(SimFaultCode.HEATER_FAIL, 1.0)  # welded relay: full power whatever the node says
    bench.step(bench.tick_s)
    assert state(bench) is NodeState.ARMED and node.heater_on and node.fault_bits == 0
    for _ in range(small.interlock.e2e_error_limit):
        bench.ctl_bus.send(corrupt_setpoints(bench))
    quiet_s = 2.0 * max(small.furnace.setpoint_refresh_s, small.timing.watchdog_timeout_s) + 60.0
    bench.clock.advance(quiet_s)  # one tick after a long silence: every cause fires in it
    node.tick()
    together = FaultFlag.OVERTEMP | FaultFlag.WATCHDOG | FaultFlag.E2E_LINK | FaultFlag.HEATER_TIMEOUT
    assert node.fault_bits & together == together, node.fault_bits
    assert node.first_fault is FaultCode.of(_lowest(node.fault_bits))
    bench.collect()
    assert bench.latest(NodeStatus).fault_bits & together == together
    bench.step(0.1)  # heartbeats again; the link is still faulted, the furnace still over temperature
    bench.command(CommandCode.RESET)
    bench.step(bench.tick_s)
    assert state(bench) is NodeState.FAULT
    assert node.last_refusal is RefusalCode.FAULT_LATCHED


def test_a_drive_whose_sensor_reads_rest_is_not_at_rest_while_its_model_still_turns(
    config: MillConfig, make_bench: Callable[..., Bench]
) -> None:
    """A dead speed sensor (stuck at 0) on a drive turning below the stall check's threshold: the node's
    reference model says the drive still turns after zero setpoints, so the node stays RUNNING, is not at
    standstill and refuses DISARM until the model is at rest too (docs/safety.md#mutation-testing: `_at_rest`)."""
    tolerance_rpm = config.interlock.measurement_tolerance_rpm
    for turning in ((10.0, 0.0), (0.0, 10.0)):  # each drive alone, below STALL_MIN_TOLERANCES × tolerance
        bench = make_bench(fault_injection=True)
        node = bench.node
        bench.step(bench.tick_s)
        bench.inject(SimFaultCode.SENSOR_STUCK)  # at standstill: both sensors read 0 from now on
        bench.arm()
        bench.hold = Setpoints(*turning, 25.0, False)  # refreshed as the controller does (SAFETY 26)
        bench.step(1.5)
        assert state(bench) is NodeState.RUNNING and node.fault_bits == 0, turning
        assert node.measured_speeds_rpm == (0.0, 0.0)
        bench.hold = Setpoints(0.0, 0.0, 25.0, False)
        bench.setpoints(0.0, 0.0)
        bench.step(bench.tick_s)
        assert max(node.true_speeds_rpm) > tolerance_rpm, turning
        assert not node.at_standstill, turning
        assert state(bench) is NodeState.RUNNING, turning
        bench.command(CommandCode.DISARM)
        bench.step(bench.tick_s)
        assert state(bench) is NodeState.RUNNING, turning
        assert node.last_refusal in (RefusalCode.WRONG_STATE, RefusalCode.NOT_STANDSTILL), turning
        bench.step(2.0)
        assert state(bench) is NodeState.ARMED and node.at_standstill, turning
        bench.command(CommandCode.DISARM)
        bench.step(bench.tick_s)
        assert state(bench) is NodeState.DISABLED, turning


def test_a_faulted_e2e_link_is_a_cause_gone_once_no_frame_has_been_in_error_for_its_quiet_time(
    bench: Bench,
) -> None:
    """SAFETY 25 (issue 37 item 1): in FAULT nobody sends good Setpoints frames to heal the score; once none has
    arrived in error for the quiet time (the genuine sender's time for e2e_error_limit frames), RESET is taken."""
    node = bench.node
    bench.arm()
    for _ in range(bench.config.interlock.e2e_error_limit + 1):
        bench.ctl_bus.send(corrupt_setpoints(bench))
    bench.step(bench.tick_s)
    assert state(bench) is NodeState.FAULT and node.link.faulted
    quiet_s = node.link.quiet_s(Setpoints)
    assert quiet_s == bench.config.interlock.e2e_error_limit * bench.config.timing.setpoint_period_s
    bench.step(quiet_s - 0.1)
    bench.command(CommandCode.RESET)
    bench.step(bench.tick_s)
    assert state(bench) is NodeState.FAULT and node.last_refusal is RefusalCode.FAULT_LATCHED
    bench.step(0.1)
    assert node.link.faulted  # the score has not healed: no good Setpoints frame came
    bench.command(CommandCode.RESET)
    bench.step(bench.tick_s)
    assert state(bench) is NodeState.DISABLED and node.fault_bits == 0

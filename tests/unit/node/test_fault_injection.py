"""Every fault injection ends in its documented state (docs/operations.md, "Fault injection")."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from firmware_sim.faults import BABBLE_ID
from millctl.protocol import (
    CommandCode,
    DriveTelemetry,
    FaultCode,
    FaultFlag,
    NodeState,
    NodeStatus,
    SimFaultCode,
)

from .conftest import Bench


@pytest.fixture
def fi_bench(make_bench: Callable[..., Bench]) -> Bench:
    bench = make_bench(fault_injection=True, seed=7)
    bench.run_at(60.0, 300.0)
    bench.hold = None  # a controller stops refreshing setpoints once the node faults
    return bench


def _reset_after_clear(bench: Bench) -> None:
    """CLEAR, let the stop finish, RESET: the node must end DISABLED with no faults."""
    bench.inject(SimFaultCode.CLEAR)
    bench.step(6.0)
    bench.command(CommandCode.RESET)
    bench.step(bench.tick_s)
    assert bench.node.state is NodeState.DISABLED
    assert bench.node.fault_bits == 0


def test_injection_is_ignored_without_the_flag(bench: Bench) -> None:
    bench.run_at(60.0, 300.0)
    bench.inject(SimFaultCode.VIB_STALL)
    bench.step(2.0)
    assert bench.node.state is NodeState.RUNNING
    assert bench.node.faults.ignored == 1


def test_vib_stall_latches_stall_and_reset_waits_for_clear(fi_bench: Bench) -> None:
    bench = fi_bench
    bench.inject(SimFaultCode.VIB_STALL)
    bench.step(5.0)
    assert bench.node.state is NodeState.FAULT
    assert bench.node.first_fault is FaultCode.STALL
    bench.step(5.0)
    bench.command(CommandCode.RESET)
    bench.step(bench.tick_s)
    assert bench.node.state is NodeState.FAULT and bench.node.last_refusal.name == "FAULT_LATCHED"
    _reset_after_clear(bench)


def test_rotary_runaway_trips_envelope_then_overspeed(fi_bench: Bench) -> None:
    bench = fi_bench
    bench.inject(SimFaultCode.ROTARY_RUNAWAY, 450.0)
    bench.step(10.0)
    assert bench.node.state is NodeState.FAULT
    assert bench.node.first_fault is FaultCode.ENVELOPE
    assert FaultFlag.OVERSPEED in bench.node.fault_bits
    assert bench.node.true_speeds_rpm[0] > 400.0  # the runaway keeps going: the node cannot stop it
    bench.command(CommandCode.RESET)
    bench.step(bench.tick_s)
    assert bench.node.last_refusal.name == "NOT_STANDSTILL"
    bench.inject(SimFaultCode.CLEAR)
    bench.step(13.0)
    bench.command(CommandCode.RESET)
    bench.step(bench.tick_s)
    assert bench.node.state is NodeState.DISABLED


@pytest.mark.parametrize("code", [SimFaultCode.SENSOR_STUCK, SimFaultCode.SENSOR_NOISY])
def test_sensor_faults_latch_sensor(fi_bench: Bench, code: SimFaultCode) -> None:
    bench = fi_bench
    bench.inject(code, 0.0)
    bench.step(1.0)
    assert bench.node.state is NodeState.FAULT
    assert bench.node.first_fault is FaultCode.SENSOR
    bench.step(5.0)
    bench.command(CommandCode.RESET)
    bench.step(bench.tick_s)
    assert bench.node.state is NodeState.FAULT
    _reset_after_clear(bench)


def test_node_silent_stops_transmitting_and_its_watchdog_stops_the_mill(fi_bench: Bench) -> None:
    """A node nobody hears gets no fresh heartbeat: the controller can only echo challenges it received."""
    bench = fi_bench
    bench.inject(SimFaultCode.NODE_SILENT)
    bench.step(bench.tick_s)
    bench.received.clear()
    bench.step(1.0)
    assert bench.received == []
    assert bench.node.state is NodeState.FAULT and bench.node.first_fault is FaultCode.WATCHDOG
    assert bench.node.link.expired_echoes > 0  # heartbeats kept coming, echoing challenges that expired
    bench.inject(SimFaultCode.NODE_SILENT, active=False)
    bench.step(0.2)
    assert bench.latest(NodeStatus).state is NodeState.FAULT


def test_node_babble_floods_the_bus_at_the_requested_rate(fi_bench: Bench) -> None:
    bench = fi_bench
    bench.hold = bench.node.last_setpoint  # the controller goes on refreshing: the node stays RUNNING (SAFETY 26)
    bench.inject(SimFaultCode.NODE_BABBLE, 2000.0)
    bench.step(bench.tick_s)
    bench.frame_ids.clear()
    bench.step(1.0)
    assert 1800 <= bench.frame_ids.count(BABBLE_ID) <= 2200
    assert bench.node.state is NodeState.RUNNING
    bench.inject(SimFaultCode.CLEAR)
    bench.step(0.1)
    bench.frame_ids.clear()
    bench.step(0.2)
    assert bench.frame_ids and BABBLE_ID not in bench.frame_ids


def test_tx_loss_drops_the_given_share_of_frames(fi_bench: Bench) -> None:
    bench = fi_bench
    bench.hold = bench.node.last_setpoint  # the controller goes on refreshing: the node stays RUNNING (SAFETY 26)
    bench.inject(SimFaultCode.TX_LOSS, 0.5)
    bench.step(bench.tick_s)
    bench.received.clear()
    bench.step(4.0)
    drive_frames = sum(1 for d in bench.received if d.kind is DriveTelemetry)
    assert 0.3 * 200 < drive_frames < 0.7 * 200
    assert bench.node.state is NodeState.RUNNING


def test_tx_corrupt_makes_every_protected_frame_fail_its_crc_and_the_watchdog_stops_the_mill(
    fi_bench: Bench,
) -> None:
    bench = fi_bench
    bench.inject(SimFaultCode.TX_CORRUPT, 1.0)
    bench.step(bench.tick_s)
    bench.received.clear()
    bench.step(1.0)
    protected = [d for d in bench.received if d.kind in (NodeStatus, DriveTelemetry)]
    assert protected and not any(d.crc_ok for d in protected)
    # nobody can read the node's challenges, so no heartbeat is fresh: its watchdog stops the mill
    assert bench.node.state is NodeState.FAULT and bench.node.first_fault is FaultCode.WATCHDOG


def test_safety_6_measured_pair_outside_for_debounce_samples_trips_envelope(fi_bench: Bench) -> None:
    bench = fi_bench
    ticks: list[tuple[bool, NodeState]] = []
    bench.on_tick.append(
        lambda b: ticks.append((not b.envelope.check_measured(*b.node.measured_speeds_rpm).ok, b.node.state))
    )
    bench.inject(SimFaultCode.ROTARY_RUNAWAY, 300.0)
    bench.step(5.0)
    trip = next(i for i, (_, state) in enumerate(ticks) if state is NodeState.FAULT)
    debounce = bench.config.interlock.debounce_samples
    assert [outside for outside, _ in ticks[trip - debounce : trip + 1]] == [False] + [True] * debounce
    assert bench.node.first_fault is FaultCode.ENVELOPE

"""The fixtures and helpers of the hil scenario suite (tests/hil/test_scenarios.py).

The ``mill`` fixtures take the module's shared service and node
(tests/hil/mill_pool.py) or start a pair of their own; the helpers read the
probe's capture. Kept apart so that the suite's scenarios read alone; the
scenario modules import the fixtures by name.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from firmware_sim.motion import Motion
from millctl.protocol import (
    DriveTelemetry,
    NodeStatus,
)
from millctl.safety import SpeedPoint
from tests.hil.conftest import pooled_mill
from tests.hil.mill_pool import MillKind
from tests.hil.scenario_support import (
    STANDSTILL_RPM,
    Mill,
    Probe,
    Seen,
    mill_on,
)

if TYPE_CHECKING:
    from tests.hil.conftest import Spawner, Transport
    from tests.hil.mill_pool import MillPool

NEEDS_PROBE = "needs the node as a separate process and a bus probe: python-can's virtual bus stays inside one process"

# Operating points: short ramps where the scenario does not need the paper's point (180/800 rpm).
LOW_RPM = (60.0, 300.0)
"""ω_r, ω_v (rpm) for scenarios that only need the mill turning."""
BABBLE_HZ = 1000.0
"""Junk frames per second from the babbling node (udp_multicast: each process reads every one)."""
LOSS_PHASE_FRAMES = 75
"""DriveTelemetry frames per loss phase (1.5 s at its 50 Hz)."""
OCCASIONAL_CORRUPTION = 0.01
"""Probability that a frame leaves the node with one bit flipped, in the "occasional bad CRC" phase."""
STALL_RPM = (160.0, 500.0)
"""Close enough to the limit (162.2 rpm at ω_v = 500) that a stalled cam takes the pair out within a second."""


@pytest.fixture
def mill(request: pytest.FixtureRequest, transport: Transport, mill_pool: MillPool) -> Iterator[Mill]:
    """The service and the node on ``transport``, DISABLED at rest: the module's shared one (tests/hil/mill_pool.py)."""
    with pooled_mill(request, mill_pool, MillKind(transport.name)) as shared:
        yield shared


@pytest.fixture
def fresh_mill(request: pytest.FixtureRequest, transport: Transport, mill_pool: MillPool) -> Iterator[Mill]:
    """Like ``mill``, newly started: the start-up scenario sees the processes start (later ones may share it)."""
    with pooled_mill(request, mill_pool, MillKind(transport.name), fresh=True) as started:
        yield started


@pytest.fixture
def bus_mill(request: pytest.FixtureRequest, transport: Transport, mill_pool: MillPool) -> Iterator[Mill]:
    """Like ``mill``, for scenarios that need separate processes and the probe (skipped on virtual)."""
    if not transport.crosses_processes:
        pytest.skip(NEEDS_PROBE)
    with pooled_mill(request, mill_pool, MillKind(transport.name)) as shared:
        yield shared


@pytest.fixture
def own_bus_mill(transport: Transport, spawn: Spawner, tmp_path: Path) -> Iterator[Mill]:
    """Like ``bus_mill``, started for this test alone: for the scenarios that kill or restart a process."""
    if not transport.crosses_processes:
        pytest.skip(NEEDS_PROBE)
    with mill_on(transport, spawn, tmp_path) as started:
        yield started


def probe_of(mill: Mill) -> Probe:
    assert mill.probe is not None
    return mill.probe


def drive_frames(probe: Probe, after: float) -> list[Seen]:
    return probe.frames(after, lambda s: isinstance(s.message, DriveTelemetry))


def wait_standstill_on_bus(mill: Mill, after: float, timeout_s: float) -> Seen:
    """The first DriveTelemetry after ``after`` with both measured speeds below standstill."""

    def still(seen: Seen) -> bool:
        m = seen.message
        return isinstance(m, DriveTelemetry) and max(abs(m.rotary_rpm), abs(m.vibration_rpm)) < STANDSTILL_RPM

    return probe_of(mill).wait_first(still, after, mill.timeout(timeout_s), "both drives at standstill")


def stop_duration_bound_s(mill: Mill, rotary_rpm: float, vibration_rpm: float) -> float:
    """The node's controlled stop from the pair: its planned ramps, the drives' lag to rest, one status period."""
    drives = mill.config.drives
    plan = Motion(mill.config, mill.envelope).planner.plan_stop(SpeedPoint(rotary_rpm, vibration_rpm))
    lag_s = 5.0 * max(drives.rotary.time_constant_s, drives.vibration.time_constant_s)
    report_s = mill.config.timing.node_tick_s + (mill.codec.cycle_time_s(NodeStatus) or 0.0)
    return mill.bounds.scaled(plan.duration_s + lag_s + report_s)

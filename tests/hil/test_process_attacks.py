"""Faults of the processes and of the link, against the real service and node processes (issue 37, SAFETY 2, 25).

The service (``millctl serve``) and the node (``python -m firmware_sim``) run
as processes of their own on the transport under test (udp_multicast inside
``tests/hil/in_netns``; socketcan in the VM tier). Each scenario ends safely:

- six bad-CRC Setpoints frames while running at 30/150 rpm trip the mill, and a
  reset through the service (what ``millctl reset`` sends) clears the node's
  latched E2E_LINK without restarting the node;
- SIGSTOP of the service mid-recipe: the node's watchdog stops the mill; after
  SIGCONT the service trips on the node's WATCHDOG fault and a reset clears it;
- SIGSTOP of the node mid-recipe: the service trips on the stale telemetry and
  stops the recipe; after SIGCONT the node stops its drives and a reset clears
  what it latched;
- SIGSTOP of the service with a heartbeat forger taking over (every forged
  heartbeat fresh): the node's watchdog stays fed, and the node stops the
  drives because their setpoints expire (SAFETY 26), within
  ``timing.setpoint_expiry_s``.
"""

from __future__ import annotations

import contextlib
import os
import signal
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from millctl.errors import MillctlError
from millctl.protocol import DriveTelemetry, FaultCode, NodeState, NodeStatus, Setpoints
from tests.hil.adversary import Adversary
from tests.hil.scenario_support import Mill, is_status, mill_on, report_timing, wait_for

if TYPE_CHECKING:
    from tests.hil.conftest import Spawner, Transport

    Capture = pytest.CaptureFixture[str]

pytestmark = pytest.mark.hil

DEMO = Path(__file__).resolve().parents[2] / "config" / "recipes" / "demo.toml"
BURST_FRAMES = 6


@pytest.fixture
def mill(transport: Transport, spawn: Spawner, tmp_path: Path) -> Iterator[Mill]:
    if not transport.crosses_processes:
        pytest.skip("the node is a process of its own here: python-can's virtual bus stays inside one process")
    with mill_on(transport, spawn, tmp_path) as started:
        yield started


def drives_at_rest(mill: Mill) -> bool:
    """The node's newest DriveTelemetry, as the probe heard it, shows both drives below 1 rpm."""
    assert mill.probe is not None
    drives = mill.probe.latest(DriveTelemetry)
    return drives is not None and max(abs(drives.rotary_rpm), abs(drives.vibration_rpm)) < 1.0


def reset_until_disabled(mill: Mill) -> None:
    """Reset through the service as ``millctl reset`` does, once the drives are at rest; then arm again."""
    wait_for(mill.at_standstill, mill.timeout(60.0), "standstill")

    def reset() -> bool:
        with contextlib.suppress(MillctlError):  # refused while telemetry is stale or the node not yet at rest
            mill.client.reset()
        with contextlib.suppress(MillctlError):
            return bool(mill.status()["state"] == "DISABLED")
        return False

    def again() -> bool:
        if reset():
            return True
        time.sleep(mill.timeout(0.5))
        return False

    wait_for(again, mill.timeout(30.0), lambda: f"a reset to DISABLED (status {mill.status()})")
    assert mill.probe is not None
    assert mill.probe.latest(NodeStatus).state is NodeState.DISABLED
    mill.client.arm()
    mill.wait_state("ARMED")


def run_recipe(mill: Mill) -> None:
    mill.client.take_control()
    mill.client.recipe_run(DEMO)
    wait_for(
        lambda: (p := mill.client.recipe().progress) is not None and p.state == "RUNNING" and not mill.at_standstill(),
        mill.timeout(30.0),
        "the recipe to run the drives",
    )


def test_a_bad_crc_burst_trips_and_a_reset_through_the_service_clears_it_without_restarting_the_node(
    mill: Mill,
) -> None:
    assert mill.probe is not None and mill.node is not None
    adversary = Adversary(mill.config.bus, mill.codec)
    try:
        mill.run_at(30.0, 150.0)
        node_pid = mill.node.pid
        t_burst = adversary.send(*[adversary.bad_crc(Setpoints(30.0, 150.0, 25.0, False))] * BURST_FRAMES)
        mill.probe.wait_first(is_status(NodeState.FAULT, FaultCode.E2E_LINK), t_burst, mill.timeout(10.0),
                              "NodeStatus FAULT/E2E_LINK")
        assert "E2E_LINK" in mill.wait_state("TRIPPED", 10.0)["trip_cause"]
        reset_until_disabled(mill)
        assert mill.node.poll() is None and mill.node.pid == node_pid  # the same node process throughout
    finally:
        adversary.close()


def test_sigstop_of_the_service_mid_recipe_the_node_stops_the_mill_and_the_service_trips_after_sigcont(
    mill: Mill,
) -> None:
    assert mill.probe is not None and mill.service is not None
    run_recipe(mill)
    t_stop = mill.probe.now()
    os.kill(mill.service.pid, signal.SIGSTOP)
    try:
        mill.probe.wait_first(is_status(NodeState.FAULT, FaultCode.WATCHDOG), t_stop, mill.timeout(10.0),
                              "the node's watchdog to latch")
        wait_for(lambda: drives_at_rest(mill), mill.timeout(60.0), "the node to bring the drives to rest")
    finally:
        os.kill(mill.service.pid, signal.SIGCONT)
    status = mill.wait_state("TRIPPED", 20.0)
    assert "WATCHDOG" in status["trip_cause"], status["trip_cause"]
    wait_for(lambda: not mill.client.recipe().active, mill.timeout(20.0), "the recipe to stop")
    assert mill.outside_envelope(mill.probe.frames(t_stop)) == []
    reset_until_disabled(mill)


def test_sigstop_of_the_node_mid_recipe_the_service_trips_and_the_node_stops_after_sigcont(mill: Mill) -> None:
    assert mill.probe is not None and mill.node is not None
    run_recipe(mill)
    t_stop = mill.probe.now()
    os.kill(mill.node.pid, signal.SIGSTOP)
    try:
        status = mill.wait_state("TRIPPED", 20.0)
        assert "stale" in status["trip_cause"] or "NodeStatus" in status["trip_cause"], status["trip_cause"]
        wait_for(lambda: not mill.client.recipe().active, mill.timeout(20.0), "the recipe to stop")
    finally:
        os.kill(mill.node.pid, signal.SIGCONT)
    wait_for(lambda: drives_at_rest(mill), mill.timeout(60.0), "the node to bring the drives to rest")
    assert mill.outside_envelope(mill.probe.frames(t_stop)) == []
    reset_until_disabled(mill)


def test_a_heartbeat_forger_cannot_keep_the_mill_running_once_the_service_is_stopped(
    mill: Mill, capsys: Capture
) -> None:
    assert mill.probe is not None and mill.service is not None
    timing = mill.config.timing
    adversary = Adversary(mill.config.bus, mill.codec)
    try:
        mill.run_at(30.0, 150.0)
        forger = adversary.keep_alive(silent_after_s=timing.heartbeat_period_s)
        wait_for(lambda: forger.genuine_counter is not None, mill.timeout(5.0), "the forger to hear a heartbeat")
        t_stop = mill.probe.now()
        os.kill(mill.service.pid, signal.SIGSTOP)
        try:
            seen = mill.probe.wait_first(is_status(NodeState.STOPPING), t_stop, mill.timeout(10.0),
                                         "the node to stop on its expired setpoints")
            wait_for(lambda: drives_at_rest(mill), mill.timeout(30.0), "the drives to rest")
            # The node ends its stop in ARMED once its stop profile is done and the drives are at rest: that
            # status may come a frame or two after the telemetry below 1 rpm (a loaded host), so it is waited for.
            armed = mill.probe.wait_first(is_status(NodeState.ARMED), seen.t, mill.timeout(10.0),
                                          "the node to end its controlled stop in ARMED")
            assert forger.sent > 0
            statuses = [s.of(NodeStatus) for s in mill.probe.frames(t_stop, is_status()) if s.t <= armed.t]
            assert all(s.state is not NodeState.FAULT for s in statuses), "the forged heartbeats fed the watchdog"
            forger.stop()
        finally:
            os.kill(mill.service.pid, signal.SIGCONT)
        measured_s = seen.t - t_stop
        bound_s = mill.bounds.scaled(timing.setpoint_expiry_s + timing.setpoint_period_s)
        report_timing(capsys, "setpoints_expire_under_a_heartbeat_forger", mill.transport.name, measured_s, bound_s)
        assert measured_s <= bound_s
        mill.wait_state("TRIPPED", 20.0)  # it never commanded the stop (or heard no node while stopped)
        reset_until_disabled(mill)
    finally:
        adversary.close()

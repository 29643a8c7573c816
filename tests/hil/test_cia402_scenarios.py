"""The mill's hil scenarios on standard CiA 402 drives (issue 36 part 5): the service and the simulated drives.

The scenarios of test_scenarios.py that are about the mill rather than the
millbus wire, with ``config/mill-cia402.toml``: ``millctl serve`` and
``python -m firmware_sim`` (both CiA 402 drives in one process, canopen
LocalNodes) as separate processes on udp_multicast (inside
``tests/hil/in_netns``) or socketcan (vcan0, the VM); on ``virtual`` the
service embeds the simulated drives. The probe reads the drives' own frames:
TPDO1 (statusword, velocity actual), heartbeats and EMCY.

The VM is the slowest tier: only start-up, E-stop, the watchdog after SIGKILL
and a recipe run have a socketcan case (``VM_CASES``); the others run on the
host's transports.
"""

from __future__ import annotations

import re
import struct
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from firmware_sim.cia402.power import PowerState, state_of
from millctl.api import RunState
from millctl.client import InterlockRefusal
from millctl.protocol import SimFaultCode
from tests.hil.scenario_support import STANDSTILL_RPM, Mill, Probe, Seen, mill_on, report_timing, wait_for

if TYPE_CHECKING:
    from tests.hil.conftest import Spawner, Transport

pytestmark = pytest.mark.hil

DEMO = Path(__file__).resolve().parents[2] / "config" / "recipes" / "demo.toml"
LOW_RPM = (60.0, 300.0)
"""ω_r, ω_v (rpm) for scenarios that only need the mill turning."""
STALL_RPM = (160.0, 500.0)
"""Close to the eq. 9 limit (162.2 rpm at ω_v = 500): a stalled cam takes the pair out within a second."""
HOST = ["udp_multicast"]
"""Transports of the scenarios without a VM case (the host's namespace only)."""
VM_CASES = ["udp_multicast", "socketcan"]
"""Transports of start-up, E-stop, watchdog after SIGKILL and the recipe run (the vcan VM runs socketcan)."""
WITH_EMBEDDED = ["virtual", *VM_CASES]
"""The same, plus ``virtual``: ``millctl serve`` with the simulated drives embedded."""
STOPPED = frozenset({PowerState.QUICK_STOP_ACTIVE, PowerState.SWITCH_ON_DISABLED, PowerState.FAULT,
                     PowerState.FAULT_REACTION_ACTIVE})


@pytest.fixture
def mill(transport: Transport, spawn: Spawner, tmp_path: Path) -> Iterator[Mill]:
    """The service and the simulated CiA 402 drives on ``transport``, seen by the controller (DISABLED)."""
    with mill_on(transport, spawn, tmp_path, backend="cia402") as started:
        yield started


def node_ids(mill: Mill) -> dict[str, int]:
    drives = mill.config.drives
    assert drives.rotary.cia402 is not None and drives.vibration.cia402 is not None
    return {"rotary": drives.rotary.cia402.node_id, "vibration": drives.vibration.cia402.node_id}


def tpdo(seen: Seen) -> tuple[PowerState | None, float]:
    """A TPDO1 as (power state, velocity actual in drive units)."""
    status, velocity = struct.unpack_from("<Hi", bytes(seen.frame.data).ljust(6, b"\x00"))
    return state_of(status), float(velocity)


def tpdos(probe: Probe, node_id: int, after: float) -> list[Seen]:
    return probe.frames(after, lambda s: s.frame.arbitration_id == 0x180 + node_id and len(s.frame.data) >= 6)


def mill_rpm(mill: Mill, motor: str, velocity: float) -> float:
    cia = getattr(mill.config.drives, motor).cia402
    return float(cia.mill_rpm(round(velocity)))


def drives_at_rest(
    mill: Mill, probe: Probe, after: float, *, stopped: bool = True
) -> tuple[float, dict[str, PowerState | None]] | None:
    """When both drives' TPDO1 showed a velocity below standstill after ``after`` (else None).

    ``stopped``: and a state the drive reaches only by a quick stop, a fault or disabling (not OPERATION
    ENABLED at zero velocity, as a controlled stop leaves it).
    """
    times, states = [], {}
    for motor, node_id in node_ids(mill).items():
        rest = [s for s in tpdos(probe, node_id, after)
                if (tpdo(s)[0] in STOPPED or not stopped) and abs(mill_rpm(mill, motor, tpdo(s)[1])) < STANDSTILL_RPM]
        if not rest:
            return None
        times.append(rest[0].t)
        states[motor] = tpdo(rest[0])[0]
    return max(times), states


def probe_of(mill: Mill) -> Probe:
    assert mill.probe is not None
    return mill.probe


def quick_stop_bound_s(mill: Mill, speeds: tuple[float, float]) -> float:
    """From a drive's quick stop to its rest: the 0x6085 ramp (the drive's max_accel) and 5 time constants."""
    drives = mill.config.drives
    ramp_s = max(speeds[0] / drives.rotary.max_accel_rpm_s, speeds[1] / drives.vibration.max_accel_rpm_s)
    lag_s = 5.0 * max(drives.rotary.time_constant_s, drives.vibration.time_constant_s)
    period_s = 0.05  # TPDO1's event timer (config/cia402-drive.eds)
    return mill.bounds.scaled(ramp_s + lag_s + period_s + mill.config.timing.node_tick_s)


# --- the operator's day -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("transport", WITH_EMBEDDED, indirect=True)
def test_startup_arm_ramp_steady_milling_and_controlled_stop(mill: Mill) -> None:
    start = mill.status()
    assert max(abs(start["measured_rotary_rpm"]), abs(start["measured_vibration_rpm"])) < STANDSTILL_RPM
    mill.run_at(*LOW_RPM)
    t_steady = time.time()
    window = mill.watch(1.0)
    for steady in window:
        assert steady["state"] == "RUNNING", steady["trip_cause"]
    mill.client.take_control()
    t_stop = time.time()
    mill.client.stop()
    wait_for(lambda: mill.status()["state"] == "ARMED" and mill.at_standstill(), mill.timeout(30.0),
             "the controlled stop to end ARMED at standstill")
    if mill.probe is not None:  # the drives' own reports of the steady window before the stop
        tolerance = mill.config.interlock.measurement_tolerance_rpm
        for motor, node_id in node_ids(mill).items():  # the window the status was watched in, not the ramp before it
            speeds = [mill_rpm(mill, motor, tpdo(s)[1]) for s in tpdos(mill.probe, node_id, t_steady)
                      if s.t < t_stop]
            assert len(speeds) >= 5, f"{len(speeds)} TPDO1 from the {motor} drive in the steady window"
            assert sum(speeds) / len(speeds) == pytest.approx(LOW_RPM[motor == "vibration"], abs=tolerance)


@pytest.mark.parametrize("transport", HOST, indirect=True)
def test_over_limit_request_refused(mill: Mill) -> None:
    mill.run_at(180.0, 800.0)
    with pytest.raises(InterlockRefusal, match=r"250\.0 rpm exceeds the limit 190\.0 rpm at ω_v = 800\.0 rpm"):
        mill.client.set_speeds(250.0, 800.0)
    assert mill.status()["state"] == "RUNNING"


@pytest.mark.parametrize("transport", VM_CASES, indirect=True)
def test_estop_quick_stops_both_drives(mill: Mill, transport: Transport, capsys: pytest.CaptureFixture[str]) -> None:
    probe = probe_of(mill)
    mill.run_at(*LOW_RPM)
    t_estop = probe.now()
    mill.client.estop()
    rest = wait_for(lambda: drives_at_rest(mill, probe, t_estop), mill.timeout(30.0), "both drives stopped at rest")
    report_timing(capsys, "cia402_estop_to_rest", transport.name, rest[0] - t_estop, quick_stop_bound_s(mill, LOW_RPM))
    assert rest[0] - t_estop <= quick_stop_bound_s(mill, LOW_RPM) + mill.bounds.scaled(0.2)
    assert mill.wait_state("TRIPPED")["trip_cause"]


# --- failures of the machine -------------------------------------------------------------------------------------


@pytest.mark.parametrize("transport", HOST, indirect=True)
@pytest.mark.parametrize(
    ("fault", "speeds"),
    [(SimFaultCode.VIB_STALL, STALL_RPM), (SimFaultCode.ROTARY_RUNAWAY, LOW_RPM), (SimFaultCode.NODE_SILENT, LOW_RPM)],
    ids=["stall", "runaway", "stale-telemetry"],
)
def test_a_failing_drive_trips_and_the_mill_stops(mill: Mill, fault: SimFaultCode, speeds: tuple[float, float]) -> None:
    probe = probe_of(mill)
    mill.run_at(*speeds)
    t_fault = probe.inject(fault)
    cause = mill.wait_state("TRIPPED", 10.0)["trip_cause"]
    assert cause
    if fault is SimFaultCode.NODE_SILENT:
        assert re.search(r"stale|heartbeat", cause), cause
        probe.inject(SimFaultCode.NODE_SILENT, active=False)  # the drives speak again: their rest shows on the bus
    if fault is not SimFaultCode.ROTARY_RUNAWAY:  # a runaway rotor ignores its drive's stop (an STO's case)
        wait_for(lambda: drives_at_rest(mill, probe, t_fault, stopped=False), mill.timeout(30.0), "both drives at rest")
    assert mill.status()["state"] == "TRIPPED"  # latched


@pytest.mark.parametrize("transport", VM_CASES, indirect=True)
def test_service_sigkilled_the_drives_stop_within_consumer_time_plus_quick_stop(
    mill: Mill, transport: Transport, capsys: pytest.CaptureFixture[str]
) -> None:
    probe = probe_of(mill)
    mill.run_at(*LOW_RPM)
    controller_heartbeat = 0x700 + mill.config.drives.controller_node_id
    mill.kill(mill.service)
    t_kill = probe.now()
    rest = wait_for(lambda: drives_at_rest(mill, probe, t_kill - 1.0), mill.timeout(30.0), "both drives at rest")
    last = probe.frames(where=lambda s: s.frame.arbitration_id == controller_heartbeat and s.t < rest[0])[-1]
    consumer_s = mill.config.timing.watchdog_timeout_s  # 0x1016 sub1's time (the contract: the watchdog timeout)
    bound_s = consumer_s + quick_stop_bound_s(mill, LOW_RPM)
    report_timing(capsys, "cia402_watchdog_after_sigkill", transport.name, rest[0] - last.t, bound_s)
    assert rest[0] - last.t <= bound_s
    assert set(rest[1].values()) <= {PowerState.QUICK_STOP_ACTIVE, PowerState.SWITCH_ON_DISABLED}  # 0x6007 = 3
    emcy = [s for s in probe.frames(last.t) if s.frame.arbitration_id in {0x80 + n for n in node_ids(mill).values()}]
    assert {struct.unpack_from("<H", bytes(s.frame.data))[0] for s in emcy} >= {0x8130}  # heartbeat lost


@pytest.mark.parametrize("transport", WITH_EMBEDDED, indirect=True)
def test_the_demo_recipe_runs_to_done(mill: Mill) -> None:
    client = mill.client
    client.take_control()
    client.recipe_run(DEMO)
    wait_for(lambda: (p := client.recipe().progress) is not None and p.state in (RunState.DONE, RunState.FAILED,
                                                                                RunState.ABORTED),
             mill.timeout(180.0), "the demo recipe to finish")
    progress = client.recipe().progress
    assert progress is not None and progress.state is RunState.DONE, (progress, mill.status()["trip_cause"])
    wait_for(mill.at_standstill, mill.timeout(20.0), "standstill after the recipe")


@pytest.mark.parametrize("transport", HOST, indirect=True)
def test_a_drive_whose_limit_read_back_differs_is_refused(spawn: Spawner, transport: Transport, tmp_path: Path) -> None:
    with mill_on(transport, spawn, tmp_path, backend="cia402", node_args=("--lie-readback", "rotary:0x607F")) as mill:
        mill.client.take_control()
        mill.client.arm()
        deadline = time.monotonic() + mill.timeout(20.0)
        messages: list[str] = []
        while time.monotonic() < deadline and not any("0x607F" in m for m in messages):
            messages = [e.message for e in mill.client.events().events]
            time.sleep(0.1)
        found = [m for m in messages if "0x607F" in m]
        assert found, messages[-10:]
        assert "rotary drive (node 2): 0x607F:00 max profile velocity written" in found[0], found[0]
        assert "read back" in found[0]
        assert mill.status()["state"] != "ARMED"

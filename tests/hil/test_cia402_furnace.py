"""CiA 402 drives with the millbus furnace node on a second CAN channel (issue 36 part 4): the mill's hil scenarios.

``millctl serve`` with ``config/mill-cia402-furnace.toml``, and as separate
processes the simulated drives (``python -m firmware_sim``) on the drives'
channel and the furnace-only millbus node (``python -m firmware_sim
--furnace-only``) on the furnace's: on udp_multicast, inside
``tests/hil/in_netns``, two channels (the same group on two ports); on
``virtual`` the service embeds both. A probe on each channel reads the drives'
TPDO1 and the furnace node's NodeStatus and FurnaceTelemetry. Scenarios:
start-up, a heated step, and the E-stop reaching the drives and the furnace.
"""

from __future__ import annotations

import socket
import struct
import subprocess
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from firmware_sim.cia402.power import PowerState, state_of
from millctl.protocol import FaultFlag, FurnaceTelemetry, NodeState, NodeStatus
from tests.hil import scenario_config, scenario_support
from tests.hil.scenario_support import STANDSTILL_RPM, Mill, Probe, Seen, wait_for

if TYPE_CHECKING:
    from tests.hil.conftest import Spawner, Transport

pytestmark = pytest.mark.hil

LOW_RPM = (60.0, 300.0)
"""ω_r, ω_v (rpm) of the heated step: the mill turning slowly while the furnace warms."""
HEAT_BY_C = 3.0
"""The heated step waits for the furnace to warm by this much (°C; 9 s at the 20 °C/min ramp)."""
TRANSPORTS = ["virtual", "udp_multicast"]


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def furnace_bus_fields(transport: Transport) -> dict[str, Any]:
    """The furnace's own channel on ``transport``: another virtual channel, or the group on another port."""
    if not transport.crosses_processes:
        return {"interface": "virtual", "channel": f"hil-furnace-{uuid.uuid4().hex[:8]}"}
    fields = transport.bus_config_fields()
    return {**fields, "options": {**fields["options"], "port": _free_udp_port()}}


class FurnaceMill(Mill):
    """The mill of :class:`Mill` on CiA 402 drives, with the furnace-only node started beside the drives."""

    furnace_probe: Probe | None = None
    """The probe on the furnace's channel (None on ``virtual``)."""
    furnace_node: subprocess.Popen[bytes] | None = None

    def start_node(self) -> subprocess.Popen[bytes]:
        """The drives' process, then the furnace node's on its own channel."""
        drives = super().start_node()
        self.furnace_node = self.spawn(
            ["python", "-m", "firmware_sim", "--config", str(self.config_path), "--furnace-only"], realtime="node"
        )
        return drives


@pytest.fixture
def mill(
    transport: Transport, spawn: Spawner, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> Iterator[FurnaceMill]:
    """Service, drives and furnace node on ``transport``, seen by the controller (DISABLED)."""
    fields = furnace_bus_fields(transport)
    write = scenario_support.write_config

    def with_furnace(directory: Path, transport: Transport, **kwargs: Any) -> Path:
        path = write(directory, transport, **kwargs)
        body = "".join(f"{key} = {scenario_config._toml_value(value)}\n" for key, value in fields.items())
        path.write_text(path.read_text(encoding="utf-8") + "[drives.furnace_bus]\n" + body, encoding="utf-8")
        return path

    monkeypatch.setitem(scenario_support.BACKEND_CONFIGS, "cia402-furnace", "mill-cia402-furnace.toml")
    monkeypatch.setattr(scenario_support, "write_config", with_furnace)
    started = FurnaceMill(transport, spawn, tmp_path, backend="cia402-furnace")
    try:
        if started.separate:
            bus = started.config.drives.furnace_bus
            assert bus is not None
            started.furnace_probe = Probe(bus, started.codec)
        started.start()
        yield started
    finally:
        if started.furnace_probe is not None:
            started.furnace_probe.close()
        started.close()
        started.kill(started.furnace_node)


def furnace_statuses(mill: FurnaceMill, after: float) -> list[NodeStatus]:
    probe = mill.furnace_probe
    assert probe is not None
    return [s.of(NodeStatus) for s in probe.frames(after, lambda s: isinstance(s.message, NodeStatus))]


def drive_states(mill: FurnaceMill, after: float) -> dict[str, list[tuple[PowerState | None, float]]]:
    """Each drive's TPDO1 after ``after``: (power state, velocity actual in drive units)."""
    probe = mill.probe
    assert probe is not None
    out = {}
    for motor in ("rotary", "vibration"):
        cia = getattr(mill.config.drives, motor).cia402
        cob_id = 0x180 + cia.node_id
        frames: list[Seen] = [s for s in probe.frames(after) if s.frame.arbitration_id == cob_id]
        words = [struct.unpack_from("<Hi", bytes(s.frame.data).ljust(6, b"\x00")) for s in frames]
        out[motor] = [(state_of(w), float(v)) for w, v in words]
    return out


@pytest.mark.parametrize("transport", TRANSPORTS, indirect=True)
def test_startup_sees_the_drives_and_the_furnace_node(mill: FurnaceMill) -> None:
    status = mill.status()
    assert status["drives_backend"] == "cia402"
    assert status["furnace_temp_c"] is not None
    assert abs(status["furnace_temp_c"] - mill.config.furnace.ambient_temp_c) < 2.0
    names = {drive["name"]: drive for drive in status["drives"]}
    assert set(names) == {"rotary", "vibration", "furnace"}
    assert names["furnace"]["state"] == "DISABLED" and "millbus furnace node on" in names["furnace"]["detail"]
    if mill.furnace_probe is not None:
        t0 = mill.furnace_probe.now()
        time.sleep(mill.timeout(0.5))
        telemetry = mill.furnace_probe.frames(t0, lambda s: isinstance(s.message, FurnaceTelemetry))
        assert telemetry, "no FurnaceTelemetry on the furnace's channel"
        assert all(s.state is NodeState.DISABLED for s in furnace_statuses(mill, t0))
        assert mill.probe is not None
        assert not mill.probe.frames(t0, lambda s: s.frame.arbitration_id in (0x100, 0x101, 0x102)), (
            "millbus frames on the drives' channel")


@pytest.mark.parametrize("transport", TRANSPORTS, indirect=True)
def test_a_heated_step_warms_the_furnace_while_the_drives_turn(mill: FurnaceMill) -> None:
    start_c = float(mill.status()["furnace_temp_c"])
    mill.run_at(*LOW_RPM)
    mill.client.set_furnace(start_c + 10.0, rate_c_per_min=20.0)

    def warm() -> dict[str, Any] | None:
        status = mill.status()
        if status["state"] == "TRIPPED":
            pytest.fail(f"tripped while the furnace heated: {status['trip_cause']}")
        temp_c = status["furnace_temp_c"]
        return status if temp_c is not None and temp_c >= start_c + HEAT_BY_C else None

    warmed = wait_for(warm, mill.timeout(60.0), f"the furnace {HEAT_BY_C} °C above {start_c:.1f} °C")
    assert warmed["state"] == "RUNNING", warmed["trip_cause"]
    assert abs(warmed["measured_rotary_rpm"] - LOW_RPM[0]) <= mill.config.interlock.measurement_tolerance_rpm
    if mill.furnace_probe is not None:
        t0 = mill.furnace_probe.now()
        time.sleep(mill.timeout(0.5))
        heating = [s.of(FurnaceTelemetry) for s in mill.furnace_probe.frames(
            t0, lambda s: isinstance(s.message, FurnaceTelemetry))]
        assert heating and all(f.heater_on for f in heating), "the furnace node does not report its heater on"
        assert all(s.state is NodeState.ARMED for s in furnace_statuses(mill, t0))


@pytest.mark.parametrize("transport", ["udp_multicast"], indirect=True)
def test_an_estop_quick_stops_the_drives_and_estops_the_furnace_node(mill: FurnaceMill) -> None:
    mill.run_at(*LOW_RPM)
    mill.client.set_furnace(float(mill.status()["furnace_temp_c"]) + 10.0)
    assert mill.furnace_probe is not None and mill.probe is not None
    t_estop = mill.furnace_probe.now()
    mill.client.estop()

    def furnace_estopped() -> NodeStatus | None:
        done = [s for s in furnace_statuses(mill, t_estop) if FaultFlag.ESTOP in s.fault_bits]
        return done[0] if done else None

    status = wait_for(furnace_estopped, mill.timeout(5.0), "the furnace node's NodeStatus with the E-stop latched")
    assert status.state is NodeState.FAULT
    probe = mill.furnace_probe

    def heater_off() -> list[FurnaceTelemetry] | None:
        seen = probe.frames(t_estop, lambda s: isinstance(s.message, FurnaceTelemetry))
        return [f for f in (s.of(FurnaceTelemetry) for s in seen) if not f.heater_on] or None

    wait_for(heater_off, mill.timeout(5.0), "the furnace node's heater off after the E-stop")

    def drives_quick_stopped() -> bool:
        states = drive_states(mill, t_estop)
        return all(any(p is PowerState.QUICK_STOP_ACTIVE or abs(v) < STANDSTILL_RPM for p, v in seen)
                   for seen in states.values())

    wait_for(lambda: drives_quick_stopped() or None, mill.timeout(30.0), "both drives quick-stopped")
    tripped = mill.wait_state("TRIPPED")
    assert "E-stop" in tripped["trip_cause"]
    wait_for(lambda: mill.at_standstill() or None, mill.timeout(30.0), "the drives at rest after the E-stop")

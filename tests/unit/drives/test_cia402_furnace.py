"""CiA 402 drives with the millbus furnace node on a second channel: the merge the controller judges (issue 36 part 4).

The controller (CiA 402 backend, ``config/mill-cia402-furnace.toml``) against
the simulated drives on one virtual bus and the furnace-only millbus node on a
second, one manual clock: a heated step, a furnace fault trips, an E-stop
reaches the furnace node, a silent furnace node trips, and a reset clears it.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Callable, Iterator

import can
import pytest

from firmware_sim.cia402.furnace_mill import Cia402FurnaceMill
from millctl.clock import ManualClock
from millctl.config import MillConfig, load_config
from millctl.config.models import Bus
from millctl.controller import Controller, ControllerState, Event
from millctl.protocol import FaultFlag, NodeState, NodeStatus, default_codec

CONFIG = "config/mill-cia402-furnace.toml"
S = ControllerState


class FurnaceRig:
    """Controller + simulated drives (drives' bus) + furnace node (furnace bus), stepped on one manual clock."""

    def __init__(self) -> None:
        loaded = load_config(CONFIG).config
        furnace_bus = Bus(interface="virtual", channel=f"rigf-{uuid.uuid4().hex}")
        self.config: MillConfig = loaded.model_copy(
            update={"drives": loaded.drives.model_copy(update={"furnace_bus": furnace_bus})})
        drives_channel = f"rigd-{uuid.uuid4().hex}"
        self.clock = ManualClock()
        self.events: list[Event] = []
        self.buses = [can.Bus(interface="virtual", channel=drives_channel) for _ in range(2)]
        self.buses += [can.Bus(interface="virtual", channel=furnace_bus.channel) for _ in range(2)]
        mill_bus, controller_bus, node_furnace_bus, self.furnace_probe = self.buses
        self.sim = Cia402FurnaceMill(self.config, mill_bus, self.clock, furnace_bus=node_furnace_bus)
        self.controller = Controller(self.config, controller_bus, self.clock, listener=self.events.append)
        self.furnace_ticks = True

    def close(self) -> None:
        self.controller.drives.close()
        self.sim.close()
        for bus in self.buses:
            bus.shutdown()

    def step(self) -> None:
        self.controller.tick()
        self.sim.mill.tick()
        if self.furnace_ticks:
            self.sim.furnace_node.tick()
        self.clock.advance(self.config.timing.controller_tick_s)
        time.sleep(0)  # let the SDO worker take the answer the tick delivered

    def run(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        for _ in range(round(seconds / self.config.timing.controller_tick_s)):
            if until is not None and until():
                return True
            self.step()
        return until() if until is not None else True

    def arm(self) -> None:
        assert self.run(30.0, lambda: self.controller.state is S.DISABLED), self.controller.trip_cause
        self.controller.arm()
        assert self.run(30.0, lambda: self.controller.state is S.ARMED), self.controller.trip_cause


@pytest.fixture
def rig() -> Iterator[FurnaceRig]:
    made = FurnaceRig()
    try:
        yield made
    finally:
        made.close()


def test_the_backend_expects_the_furnace_and_describes_its_node(rig: FurnaceRig) -> None:
    rig.arm()
    assert rig.controller.drives.has_furnace
    assert rig.sim.furnace_node.state is NodeState.ARMED
    furnace = [info for info in rig.controller.drives.describe() if info.name == "furnace"]
    assert furnace and furnace[0].state == "ARMED" and "millbus furnace node on virtual:" in furnace[0].detail


def test_a_heated_step_heats_the_furnace_node_while_the_drives_turn(rig: FurnaceRig) -> None:
    rig.arm()
    start_c = rig.sim.furnace_temp_c
    rig.controller.set_furnace(60.0, rate_c_per_min=20.0)
    rig.controller.set_speeds(60.0, 300.0)
    assert rig.run(60.0, lambda: rig.sim.furnace_temp_c > start_c + 3.0), rig.controller.trip_cause
    assert rig.controller.state is S.RUNNING, rig.controller.trip_cause
    assert rig.sim.heater_on
    furnace = rig.controller.furnace
    assert furnace is not None and furnace.temp_c > start_c + 2.0
    assert min(rig.sim.true_speeds_rpm) > 50.0


def test_a_furnace_fault_trips_the_mill_and_names_the_furnace_node(rig: FurnaceRig) -> None:
    rig.arm()
    rig.controller.set_speeds(60.0, 300.0)
    assert rig.run(20.0, lambda: rig.controller.state is S.RUNNING)
    rig.sim.furnace_node.furnace.temp_c = rig.config.furnace.over_temp_c + 10.0
    assert rig.run(3.0, lambda: rig.controller.state is S.TRIPPED)
    cause = rig.controller.trip_cause
    assert "furnace node" in cause and "OVERTEMP" in cause, cause
    assert rig.run(20.0, lambda: max(rig.sim.true_speeds_rpm) < 1.0), "the drives did not stop after the trip"


def test_an_estop_reaches_the_furnace_node_and_is_shown_when_all_took_it(rig: FurnaceRig) -> None:
    rig.arm()
    rig.controller.set_furnace(60.0)
    rig.controller.set_speeds(60.0, 300.0)
    assert rig.run(20.0, lambda: rig.sim.heater_on and rig.controller.state is S.RUNNING)
    rig.controller.estop()
    assert rig.run(2.0, lambda: FaultFlag.ESTOP in rig.sim.furnace_node.fault_bits)
    assert rig.sim.furnace_node.state is NodeState.FAULT and not rig.sim.heater_on
    status = rig.controller.node_status
    assert rig.run(2.0, lambda: rig.controller.node_status is not None
                   and FaultFlag.ESTOP in rig.controller.node_status.fault_bits)
    status = rig.controller.node_status
    assert status is not None and status.state is NodeState.FAULT
    assert "furnace node E-stopped" in rig.controller.drives.fault_detail()


def test_a_silent_furnace_node_trips_the_mill(rig: FurnaceRig) -> None:
    rig.arm()
    rig.controller.set_speeds(60.0, 300.0)
    assert rig.run(20.0, lambda: rig.controller.state is S.RUNNING)
    rig.furnace_ticks = False
    assert rig.run(3.0, lambda: rig.controller.state is S.TRIPPED)
    cause = rig.controller.trip_cause  # the controller's FurnaceTelemetry track and the link's NodeStatus age
    assert "FurnaceTelemetry stale" in cause or ("furnace node" in cause and "silent" in cause), cause


def test_the_link_calls_a_furnace_node_silent_past_its_bound(rig: FurnaceRig) -> None:
    rig.arm()
    drives = rig.controller.drives
    link = drives.furnace  # type: ignore[attr-defined]
    assert link.faults(rig.clock.now(), estop_commanded=False) == []
    later_s = link.status_s + link.stale_after_s + 0.01
    (flag, cause), = link.faults(later_s, estop_commanded=False)
    assert flag is FaultFlag.E2E_LINK and "silent: NodeStatus age" in cause and f"{link.stale_after_s:.2f} s" in cause


def test_a_reset_after_a_cleared_furnace_fault_comes_back_disabled(rig: FurnaceRig) -> None:
    rig.arm()
    rig.sim.furnace_node.furnace.temp_c = rig.config.furnace.over_temp_c + 10.0
    assert rig.run(3.0, lambda: rig.controller.state is S.TRIPPED)
    rig.sim.furnace_node.furnace.temp_c = rig.config.furnace.ambient_temp_c
    assert rig.run(5.0, lambda: rig.sim.at_standstill)
    rig.controller.reset()
    assert rig.run(10.0, lambda: rig.controller.state is S.DISABLED), rig.controller.trip_cause
    assert rig.sim.furnace_node.state is NodeState.DISABLED and not rig.sim.furnace_node.fault_bits


def test_corrupt_furnace_frames_trip_the_mill_on_e2e(rig: FurnaceRig) -> None:
    rig.arm()
    codec = default_codec()
    for counter in range(rig.config.interlock.e2e_error_limit + 1):  # a NodeStatus whose CRC does not match
        frame = codec.encode(NodeStatus(NodeState.ARMED), counter)
        frame.data[-1] ^= 0xFF
        rig.furnace_probe.send(frame)
    assert rig.run(1.0, lambda: rig.controller.state is S.TRIPPED)
    cause = rig.controller.trip_cause
    assert "furnace node on virtual:" in cause and "E2E_LINK" in cause, cause

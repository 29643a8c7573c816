"""The controller on CiA 402 drives (the simulated ones of firmware_sim.cia402): start-up, arm, moves, stops, trips."""

from __future__ import annotations

from pathlib import Path

import can
import pytest

from millctl.clock import ManualClock
from millctl.config import load_config
from millctl.controller import Controller, ControllerState
from millctl.safety import InterlockRefused
from tests.unit.drives.rig402 import Rig402

S = ControllerState


def _measured_at_rest(rig: Rig402) -> bool:
    measured = rig.controller.measured
    return measured is not None and max(abs(measured.rotary_rpm), abs(measured.vibration_rpm)) < 1.0


def test_start_up_configures_both_drives_and_reports_them_disabled(rig: Rig402) -> None:
    rig.connect()
    info = {d.name: d for d in rig.controller.drives.describe()}
    assert info["rotary"].node_id == 2 and info["vibration"].node_id == 3
    assert all(d.state == "SWITCH ON DISABLED" for d in info.values())
    assert all("vendor 0x" in d.detail for d in info.values())  # the identity object 0x1018, read at start-up
    assert rig.sim.drives["rotary"].value(0x1016, 1) == (1 << 16) | 250  # consumer of node 1, watchdog 250 ms
    assert rig.sim.drives["rotary"].value(0x6007) == 3  # quick stop on heartbeat loss


def test_the_controller_produces_its_heartbeat_and_refreshes_the_rpdos(rig: Rig402) -> None:
    rig.connect()
    rig.heard.clear()
    rig.run(1.0)
    ids = [m.arbitration_id for m in rig.heard]
    assert ids.count(0x701) >= 10 and all(m.data == b"\x05" for m in rig.heard if m.arbitration_id == 0x701)
    assert ids.count(0x202) >= 5 and ids.count(0x203) >= 5  # RPDO1 every setpoint period, even disabled


def test_arm_ramp_stop_estop_reset(rig: Rig402) -> None:
    rig.arm()
    rig.controller.set_speeds(100.0, 300.0)
    assert rig.run(60.0, lambda: rig.controller.trajectory is None and rig.controller.state is S.RUNNING)
    rig.run(3.0)
    rotary, vibration = rig.sim.true_speeds_rpm
    assert rotary == pytest.approx(100.0, abs=3.0) and vibration == pytest.approx(300.0, abs=5.0)
    rig.controller.stop()
    assert rig.run(60.0, lambda: rig.controller.state is S.ARMED), rig.controller.trip_cause
    assert rig.sim.at_standstill
    rig.controller.set_speeds(100.0, 300.0)
    rig.run(10.0)
    rig.controller.estop()
    assert rig.run(5.0, lambda: not rig.controller._estop_pending)  # both statuswords show the quick stop
    assert rig.controller.state is S.TRIPPED and "E-stop" in rig.controller.trip_cause
    assert rig.run(30.0, lambda: rig.sim.at_standstill and _measured_at_rest(rig))
    rig.controller.reset()
    assert rig.run(10.0, lambda: rig.controller.state is S.DISABLED), rig.messages("refusal")


def test_arm_disarm_arm_again_and_run(rig: Rig402) -> None:
    """An operator's routine: the second ARM's enabling is not a drive leaving OPERATION ENABLED by itself."""
    rig.arm()
    rig.controller.disarm()
    assert rig.run(10.0, lambda: rig.controller.state is S.DISABLED), rig.controller.trip_cause
    rig.controller.arm()
    assert rig.run(30.0, lambda: rig.controller.state is S.ARMED), rig.controller.trip_cause
    rig.controller.set_speeds(60.0, 300.0)
    assert rig.run(60.0, lambda: rig.controller.trajectory is None and rig.controller.state is S.RUNNING), (
        rig.controller.trip_cause)
    rig.run(2.0)
    assert rig.controller.state is S.RUNNING and not rig.controller.trip_cause


def test_a_limit_read_back_that_differs_refuses_the_arm_naming_object_and_values(rig: Rig402) -> None:
    rig.connect()
    rig.sim.drives["rotary"].lie_readback(0x607F)
    rig.controller.arm()
    assert rig.run(30.0, lambda: any("arm refused" in m for m in rig.messages("refusal")))
    refusal = next(m for m in rig.messages("refusal") if "arm refused" in m)
    written = rig.sim.drives["rotary"].value(0x607F)
    expected = f"rotary drive (node 2): 0x607F:00 max profile velocity written {written}, read back {written + 1}"
    assert expected in refusal
    rig.run(2.0)
    assert rig.controller.state is S.DISABLED
    assert all(d.state == "SWITCH ON DISABLED" for d in rig.controller.drives.describe())  # not enabled


def test_a_limit_read_back_that_differs_before_a_move_refuses_it_and_nothing_moves(rig: Rig402) -> None:
    rig.arm()
    rig.sim.drives["vibration"].lie_readback(0x6083)
    rig.controller.set_speeds(100.0, 300.0)
    assert rig.run(30.0, lambda: rig.controller.state is S.TRIPPED)
    assert "vibration drive (node 3): 0x6083:00 profile acceleration written" in rig.controller.trip_cause
    rig.run(2.0)
    assert max(abs(v) for v in rig.sim.true_speeds_rpm) < 1.0


def test_a_pair_outside_the_envelope_is_refused_exactly_as_on_millbus(rig: Rig402) -> None:
    rig.arm()
    with pytest.raises(InterlockRefused) as on_cia402:
        rig.controller.set_speeds(250.0, 800.0)
    millbus = load_config("config/mill.toml").config
    bus = can.Bus(interface="virtual", channel="refusal-millbus")
    try:
        controller = Controller(millbus, bus, ManualClock())
        controller.machine.go(S.DISABLED, "test")
        controller.machine.go(S.ARMED, "test")
        with pytest.raises(InterlockRefused) as on_millbus:
            controller.set_speeds(250.0, 800.0)
    finally:
        bus.shutdown()
    assert str(on_cia402.value) == str(on_millbus.value)


def test_an_emcy_trips_naming_the_drive_and_its_error_code(rig: Rig402) -> None:
    rig.arm()
    rig.probe.send(can.Message(arbitration_id=0x083, data=bytes([0x10, 0x81, 0x11, 0, 0, 0, 0, 0]),
                               is_extended_id=False))
    assert rig.run(5.0, lambda: rig.controller.state is S.TRIPPED)
    assert "vibration drive (node 3): EMCY 0x8110 (error register 0x11)" in rig.controller.trip_cause


@pytest.mark.parametrize("can_id", [0x202, 0x701, 0x000])
def test_a_second_sender_of_the_controllers_frames_trips(rig: Rig402, can_id: int) -> None:
    rig.arm()
    rig.probe.send(can.Message(arbitration_id=can_id, data=bytes([0x0F, 0, 0xE8, 0x03, 0, 0]), is_extended_id=False))
    assert rig.run(5.0, lambda: rig.controller.state is S.TRIPPED)
    assert f"second sender: frame 0x{can_id:03X}" in rig.controller.trip_cause


def test_drives_that_stop_answering_trip_the_controller_as_stale(rig: Rig402) -> None:
    rig.arm()
    rig.sim.tick = lambda: None  # type: ignore[method-assign]  # the drives fall silent
    assert rig.run(5.0, lambda: rig.controller.state is S.TRIPPED)
    assert "NodeStatus stale" in rig.controller.trip_cause


def test_a_controller_that_stops_ticking_is_stopped_by_the_drives_own_heartbeat_consumer(rig: Rig402) -> None:
    rig.arm()
    rig.controller.set_speeds(100.0, 300.0)
    assert rig.run(60.0, lambda: rig.controller.trajectory is None)
    rig.controller.tick = lambda: None  # type: ignore[method-assign]  # the controller is gone: no heartbeat, no RPDO
    consumer_s = rig.config.timing.watchdog_timeout_s
    rig.run(consumer_s + 0.1)  # the consumer time, and one drive tick to react
    assert all(d.state.name == "QUICK_STOP_ACTIVE" for d in rig.sim.drives.values())
    assert rig.run(30.0, lambda: rig.sim.at_standstill)


def test_a_drive_whose_heartbeat_stops_while_its_tpdos_go_on_trips_naming_it(rig: Rig402) -> None:
    rig.arm()
    rig.sim.drives["vibration"].store(0x1017, 0, 0)  # its producer heartbeat off: TPDOs still flow
    assert rig.run(5.0, lambda: rig.controller.state is S.TRIPPED)
    assert "vibration drive (node 3) heartbeat stale" in rig.controller.trip_cause


def test_a_drive_that_restarts_is_configured_again_and_the_mill_recovers_after_a_reset(rig: Rig402) -> None:
    rig.arm()
    rig.probe.send(can.Message(arbitration_id=0x000, data=bytes([0x81, 0x02]), is_extended_id=False))  # reset node 2
    assert rig.run(5.0, lambda: rig.controller.state is S.TRIPPED)
    assert rig.run(30.0, lambda: rig.controller.drives.report.started and _measured_at_rest(rig))  # type: ignore[attr-defined]
    rig.run(1.0)
    rig.controller.reset()
    assert rig.run(10.0, lambda: rig.controller.state is S.DISABLED), rig.messages("refusal")
    assert rig.sim.drives["rotary"].value(0x1016, 1) == (1 << 16) | 250  # its consumer written again
    rig.controller.arm()
    assert rig.run(30.0, lambda: rig.controller.state is S.ARMED), rig.controller.trip_cause


def test_velocity_mode_with_a_gear_ratio_runs_the_mill_at_mill_rpm(tmp_path: Path) -> None:
    text = Path("config/mill-cia402.toml").read_text().replace('mode = "profile-velocity"', 'mode = "velocity"')
    text = text.replace("gear_ratio = 1.0", "gear_ratio = 3.0")
    (tmp_path / "mill.toml").write_text(text)
    rig = Rig402(load_config(tmp_path / "mill.toml").config)
    try:
        rig.arm()
        assert rig.sim.drives["rotary"].mode == 2  # 0x6060 as the controller wrote it at start-up
        rig.controller.set_speeds(100.0, 300.0)
        assert rig.run(60.0, lambda: rig.controller.trajectory is None)
        rig.run(3.0)
        assert rig.sim.true_speeds_rpm[1] == pytest.approx(300.0, abs=5.0)
        measured = rig.controller.measured
        assert measured is not None and measured.vibration_rpm == pytest.approx(300.0, abs=5.0)
        assert rig.sim.drives["vibration"].value(0x6042) == 900  # 300 mill rpm × 3 motor rpm per mill rpm
    finally:
        rig.close()


def test_drives_shipped_without_a_heartbeat_are_configured_anyway_and_then_produce_one(rig: Rig402) -> None:
    rig.step()  # the drives boot
    for drive in rig.sim.drives.values():
        drive.store(0x1017, 0, 0)
    rig.connect()
    assert all(drive.value(0x1017) == 100 for drive in rig.sim.drives.values())
    rig.heard.clear()
    rig.run(1.0)
    assert {m.arbitration_id for m in rig.heard} >= {0x702, 0x703}

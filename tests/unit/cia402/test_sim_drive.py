"""The simulated CiA 402 drives on the wire (issue 36 part 4): what a controller sees of them.

Every test talks to the drives in frames only (SDO, NMT, RPDO1, heartbeat;
tests/unit/cia402/wire.py) and judges what comes back (TPDO1, EMCY,
heartbeats, SDO answers), stepped by a manual clock.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator

import pytest

from firmware_sim.cia402 import PowerState
from firmware_sim.cia402.drive import EMCY_HEARTBEAT, EMCY_OVERSPEED, EMCY_SENSOR, EMCY_STALL
from firmware_sim.cia402.power import state_of
from firmware_sim.faults import BABBLE_ID
from millctl.config import MillConfig
from millctl.protocol import SimFault, SimFaultCode, default_codec
from tests.unit.cia402.wire import CONTROLLER_ID, GEAR_RATIO, ROTARY_ID, VIBRATION_ID, Wire, cia402_config, wire

SHUTDOWN, SWITCH_ON, ENABLE, QUICK_STOP, FAULT_RESET = 0x06, 0x07, 0x0F, 0x0B, 0x80
MAX_RPM = 200.0
ACCEL_RPM_S = 30.0
"""Below both motors' own limit (rotary 40 rpm/s in config/mill.toml)."""
QUICK_STOP_RPM_S = 35.0
CONSUMER_MS = 250


@pytest.fixture
def w(config: MillConfig) -> Iterator[Wire]:
    rig = Wire(cia402_config(config))
    rig.step()
    yield rig
    rig.close()


def configure(w: Wire, node_id: int, *, max_rpm: float = MAX_RPM, abort_option: int = 3) -> None:
    """What the controller writes before a move: limits, ramps, quick stop, heartbeat consumer; then NMT start."""
    w.write(node_id, 0x607F, 0, wire(max_rpm), 4)
    w.write(node_id, 0x6080, 0, round(max_rpm * GEAR_RATIO), 4)
    w.write(node_id, 0x6083, 0, wire(ACCEL_RPM_S), 4)
    w.write(node_id, 0x6084, 0, wire(ACCEL_RPM_S), 4)
    w.write(node_id, 0x6085, 0, wire(QUICK_STOP_RPM_S), 4)
    w.write(node_id, 0x605A, 0, 2, 2, signed=True)
    w.write(node_id, 0x6007, 0, abort_option, 2, signed=True)
    w.write(node_id, 0x1016, 1, (CONTROLLER_ID << 16) | CONSUMER_MS, 4)
    w.nmt(0x01, node_id)


def state(w: Wire, node_id: int) -> PowerState | None:
    return state_of(w.tpdo(node_id)[0])


def enable(w: Wire, node_id: int, target: int = 0) -> None:
    for word in (SHUTDOWN, SWITCH_ON, ENABLE):
        w.run(0.1, heartbeat=True, rpdo={node_id: (word, target)})


def test_power_states_follow_the_controlword_and_show_in_the_statusword(w: Wire) -> None:
    configure(w, ROTARY_ID)
    w.run(0.1, heartbeat=True)
    assert state(w, ROTARY_ID) is PowerState.SWITCH_ON_DISABLED
    seen = []
    for word in (SHUTDOWN, SWITCH_ON, ENABLE):
        w.run(0.1, heartbeat=True, rpdo={ROTARY_ID: (word, 0)})
        seen.append(state(w, ROTARY_ID))
    assert seen == [PowerState.READY_TO_SWITCH_ON, PowerState.SWITCHED_ON, PowerState.OPERATION_ENABLED]
    w.run(0.1, heartbeat=True, rpdo={ROTARY_ID: (SWITCH_ON, 0)})  # disable operation (5)
    assert state(w, ROTARY_ID) is PowerState.SWITCHED_ON
    assert w.read(ROTARY_ID, 0x6041) == w.tpdo(ROTARY_ID)[0]  # SDO and TPDO agree


def test_pdos_flow_only_in_nmt_operational(w: Wire) -> None:
    w.run(0.5)
    assert not w.frames(0x180 + ROTARY_ID)  # PRE-OPERATIONAL: no TPDO ...
    w.run(0.2, rpdo={ROTARY_ID: (SHUTDOWN, 0)})
    assert w.mill.drives["rotary"].state is PowerState.SWITCH_ON_DISABLED  # ... and RPDO1 ignored
    assert [m.data[0] for m in w.frames(0x700 + ROTARY_ID)][-1] == 0x7F  # heartbeat says PRE-OPERATIONAL
    w.nmt(0x01, ROTARY_ID)
    mark = len(w.seen)
    w.run(0.5)
    tpdos = w.frames(0x180 + ROTARY_ID, mark)
    assert 8 <= len(tpdos) <= 12  # event timer 50 ms: about 10 in 0.5 s
    assert not w.frames(0x180 + VIBRATION_ID)  # the other drive is still PRE-OPERATIONAL
    assert [m.data[0] for m in w.frames(0x700 + ROTARY_ID, mark)][-1] == 0x05


def test_the_drive_ramps_at_the_profile_acceleration_and_reports_the_velocity_actual(w: Wire) -> None:
    configure(w, ROTARY_ID)
    enable(w, ROTARY_ID)
    w.run(0.5, heartbeat=True, rpdo={ROTARY_ID: (ENABLE, wire(60.0))})
    rotary = w.mill.drives["rotary"]
    assert rotary.demand_rpm == pytest.approx(0.5 * ACCEL_RPM_S, abs=1.0)  # 30 rpm/s for 0.5 s
    w.run(2.5, heartbeat=True, rpdo={ROTARY_ID: (ENABLE, wire(60.0))})
    status, actual = w.tpdo(ROTARY_ID)
    assert actual == pytest.approx(wire(60.0), abs=wire(3.0))
    assert status & 0x0400  # target reached
    assert w.mill.true_speeds_rpm[0] == pytest.approx(60.0, abs=1.0)


def test_the_target_is_limited_to_max_profile_velocity_and_max_motor_speed(w: Wire) -> None:
    configure(w, ROTARY_ID, max_rpm=40.0)
    enable(w, ROTARY_ID)
    w.run(3.0, heartbeat=True, rpdo={ROTARY_ID: (ENABLE, wire(150.0))})
    status, _ = w.tpdo(ROTARY_ID)
    assert w.mill.true_speeds_rpm[0] == pytest.approx(40.0, abs=1.0)
    assert status & 0x0800  # internal limit active
    w.write(ROTARY_ID, 0x607F, 0, wire(150.0), 4)  # max profile velocity raised: max motor speed still holds
    w.run(2.0, heartbeat=True, rpdo={ROTARY_ID: (ENABLE, wire(150.0))})
    assert w.mill.true_speeds_rpm[0] == pytest.approx(40.0, abs=1.0)


def test_a_drive_without_limits_written_does_not_move(w: Wire) -> None:
    w.nmt(0x01, ROTARY_ID)
    enable(w, ROTARY_ID)
    assert state(w, ROTARY_ID) is PowerState.OPERATION_ENABLED
    w.run(1.0, rpdo={ROTARY_ID: (ENABLE, wire(100.0))})
    assert w.mill.true_speeds_rpm[0] == 0.0  # the EDS defaults of 0x607F/0x6080/0x6083 are 0


def test_a_silent_controller_quick_stops_the_drive_within_consumer_time_plus_ramp(w: Wire) -> None:
    configure(w, ROTARY_ID)
    enable(w, ROTARY_ID)
    w.run(4.0, heartbeat=True, rpdo={ROTARY_ID: (ENABLE, wire(90.0))})
    assert w.mill.true_speeds_rpm[0] == pytest.approx(90.0, abs=2.0)
    mark, t_last = len(w.seen), w.clock.now()
    bound_s = CONSUMER_MS / 1000.0 + 90.0 / QUICK_STOP_RPM_S  # consumer time + the 0x6085 ramp
    lag_s = 5.0 * w.config.drives.rotary.time_constant_s  # the motor follows the demand with its lag
    stopped_s = None
    for _ in range(round((bound_s + lag_s + 1.0) / w.dt_s)):
        w.step()  # no heartbeat, no RPDO: the controller is gone
        if stopped_s is None and w.mill.true_speeds_rpm[0] < 1.0:
            stopped_s = w.clock.now() - t_last
    assert stopped_s is not None and stopped_s <= bound_s + lag_s
    emcy = w.frames(0x80 + ROTARY_ID, mark)
    assert emcy and struct.unpack_from("<H", emcy[0].data)[0] == EMCY_HEARTBEAT
    states = {state_of(m.data[0] | m.data[1] << 8) for m in w.frames(0x180 + ROTARY_ID, mark)}
    assert PowerState.QUICK_STOP_ACTIVE in states
    assert state(w, ROTARY_ID) is PowerState.SWITCH_ON_DISABLED  # 0x605A = 2: then switch on disabled
    assert w.tpdo(ROTARY_ID)[0] & 0x0080  # warning: the heartbeat is lost ...
    w.run(0.2, heartbeat=True)
    assert not w.tpdo(ROTARY_ID)[0] & 0x0080  # ... until it is heard again


def test_without_a_consumer_entry_a_silent_controller_changes_nothing(w: Wire) -> None:
    configure(w, ROTARY_ID)
    w.write(ROTARY_ID, 0x1016, 1, 0, 4)  # consumer off
    enable(w, ROTARY_ID)
    w.run(1.5, rpdo={ROTARY_ID: (ENABLE, wire(100.0))})  # no heartbeat at all
    assert state(w, ROTARY_ID) is PowerState.OPERATION_ENABLED


def test_quick_stop_by_controlword_ends_switch_on_disabled_at_rest(w: Wire) -> None:
    configure(w, VIBRATION_ID)
    enable(w, VIBRATION_ID)
    w.run(3.0, heartbeat=True, rpdo={VIBRATION_ID: (ENABLE, wire(60.0))})
    w.run(0.05, heartbeat=True, rpdo={VIBRATION_ID: (QUICK_STOP, 0)})
    assert state(w, VIBRATION_ID) is PowerState.QUICK_STOP_ACTIVE
    w.run(3.0, heartbeat=True, rpdo={VIBRATION_ID: (QUICK_STOP, 0)})
    assert w.mill.true_speeds_rpm[1] < 1.0
    assert state(w, VIBRATION_ID) is PowerState.SWITCH_ON_DISABLED


def inject(w: Wire, fault: SimFaultCode, active: bool = True, param: float = 0.0) -> None:
    w.bus.send(default_codec().encode(SimFault(fault, active, param)))


def test_a_stall_raises_emcy_and_a_fault_that_resets_only_with_the_cause_gone(w: Wire) -> None:
    configure(w, VIBRATION_ID)
    enable(w, VIBRATION_ID)
    w.run(3.0, heartbeat=True, rpdo={VIBRATION_ID: (ENABLE, wire(60.0))})
    mark = len(w.seen)
    inject(w, SimFaultCode.VIB_STALL)
    w.run(3.0, heartbeat=True, rpdo={VIBRATION_ID: (ENABLE, wire(60.0))})
    emcy = w.frames(0x80 + VIBRATION_ID, mark)
    assert emcy and struct.unpack_from("<HB", emcy[0].data) == (EMCY_STALL, 0x01)
    assert state(w, VIBRATION_ID) is PowerState.FAULT
    assert w.read(VIBRATION_ID, 0x603F) == EMCY_STALL
    w.run(0.1, heartbeat=True, rpdo={VIBRATION_ID: (FAULT_RESET, 0)})
    assert state(w, VIBRATION_ID) is PowerState.FAULT  # the cause is still there
    inject(w, SimFaultCode.CLEAR)
    w.run(0.1, heartbeat=True, rpdo={VIBRATION_ID: (0, 0)})
    w.run(0.1, heartbeat=True, rpdo={VIBRATION_ID: (FAULT_RESET, 0)})
    assert state(w, VIBRATION_ID) is PowerState.SWITCH_ON_DISABLED
    assert struct.unpack_from("<H", w.frames(0x80 + VIBRATION_ID)[-1].data)[0] == 0  # EMCY "error reset"


def test_a_runaway_past_max_motor_speed_raises_emcy(w: Wire) -> None:
    configure(w, ROTARY_ID)
    enable(w, ROTARY_ID)
    w.run(1.0, heartbeat=True, rpdo={ROTARY_ID: (ENABLE, wire(60.0))})
    mark = len(w.seen)
    inject(w, SimFaultCode.ROTARY_RUNAWAY, param=MAX_RPM + 40.0)
    w.run(6.0, heartbeat=True, rpdo={ROTARY_ID: (ENABLE, wire(60.0))})
    codes = [struct.unpack_from("<H", m.data)[0] for m in w.frames(0x80 + ROTARY_ID, mark)]
    assert codes[:1] == [EMCY_OVERSPEED]
    assert state(w, ROTARY_ID) in (PowerState.FAULT_REACTION_ACTIVE, PowerState.FAULT)


def test_a_silent_drive_sends_nothing_not_even_sdo_answers(w: Wire) -> None:
    configure(w, ROTARY_ID)
    inject(w, SimFaultCode.NODE_SILENT)
    w.step()
    mark = len(w.seen)
    w.run(0.5, heartbeat=True)
    assert [m for m in w.seen[mark:] if m.arbitration_id != 0x700 + CONTROLLER_ID] == []
    with pytest.raises(TimeoutError):
        w.read(ROTARY_ID, 0x6041)


def test_an_injected_lie_changes_the_limit_read_back_only(w: Wire) -> None:
    w.mill.drives["rotary"].lie_readback(0x607F, 0, offset=5)
    w.write(ROTARY_ID, 0x607F, 0, 4000, 4)
    assert w.read(ROTARY_ID, 0x607F) == 4005
    assert w.mill.drives["rotary"].limits().max_rpm == 0.0  # 0x6080 still 0; the drive keeps what was written
    assert w.read(VIBRATION_ID, 0x607F) == 0


def test_velocity_mode_maps_the_16_bit_vl_objects(config: MillConfig) -> None:
    w = Wire(cia402_config(config, mode="velocity"))
    try:
        w.step()
        w.write(ROTARY_ID, 0x6060, 0, 2, 1, signed=True)
        w.write(ROTARY_ID, 0x1600, 2, 0x60420010, 4)  # RPDO1: controlword + vl target (i16)
        w.write(ROTARY_ID, 0x1A00, 2, 0x60440010, 4)  # TPDO1: statusword + vl actual (i16)
        configure(w, ROTARY_ID)
        for word in (SHUTDOWN, SWITCH_ON, ENABLE):
            for _ in range(10):
                w.send(0x200 + ROTARY_ID, struct.pack("<Hh", word, wire(50.0)))
                w.step(heartbeat=True)
        for _ in range(200):
            w.send(0x200 + ROTARY_ID, struct.pack("<Hh", ENABLE, wire(50.0)))
            w.step(heartbeat=True)
        last = w.frames(0x180 + ROTARY_ID)[-1]
        assert len(last.data) == 4
        status, actual = struct.unpack("<Hh", last.data)
        assert state_of(status) is PowerState.OPERATION_ENABLED and w.read(ROTARY_ID, 0x6061) == 2
        assert actual == pytest.approx(wire(50.0), abs=wire(3.0))
    finally:
        w.close()


def test_nmt_reset_node_reboots_the_drive_with_its_defaults(w: Wire) -> None:
    configure(w, ROTARY_ID)
    enable(w, ROTARY_ID)
    mark = len(w.seen)
    w.nmt(0x81, ROTARY_ID)
    assert [bytes(m.data) for m in w.frames(0x700 + ROTARY_ID, mark)][:1] == [b"\x00"]  # boot-up
    assert w.read(ROTARY_ID, 0x607F) == 0 and w.read(ROTARY_ID, 0x1016, 1) == 0
    assert w.mill.drives["rotary"].state is PowerState.SWITCH_ON_DISABLED


def test_a_noisy_sensor_raises_the_sensor_emcy(w: Wire) -> None:
    configure(w, ROTARY_ID)
    enable(w, ROTARY_ID)
    w.run(3.0, heartbeat=True, rpdo={ROTARY_ID: (ENABLE, wire(60.0))})
    mark = len(w.seen)
    inject(w, SimFaultCode.SENSOR_NOISY, param=50.0)
    w.run(1.0, heartbeat=True, rpdo={ROTARY_ID: (ENABLE, wire(60.0))})
    codes = [struct.unpack_from("<H", m.data)[0] for m in w.frames(0x80 + ROTARY_ID, mark)]
    assert codes[:1] == [EMCY_SENSOR]
    assert state(w, ROTARY_ID) in (PowerState.FAULT_REACTION_ACTIVE, PowerState.FAULT)


def test_babble_and_frame_loss_act_on_what_the_drives_send(w: Wire) -> None:
    configure(w, ROTARY_ID)
    mark = len(w.seen)
    inject(w, SimFaultCode.NODE_BABBLE, param=1000.0)
    w.run(0.5, heartbeat=True)
    assert len(w.frames(BABBLE_ID, mark)) >= 400  # about 1000 Hz for 0.5 s
    assert w.read(ROTARY_ID, 0x6041)  # the drive still answers
    inject(w, SimFaultCode.NODE_BABBLE, active=False)
    inject(w, SimFaultCode.TX_LOSS, param=1.0)
    w.step()
    mark = len(w.seen)
    w.run(0.5, heartbeat=True)
    assert [m for m in w.seen[mark:] if m.arbitration_id != 0x700 + CONTROLLER_ID] == []
    inject(w, SimFaultCode.TX_LOSS, active=False)
    w.run(0.2, heartbeat=True)
    assert w.frames(0x180 + ROTARY_ID, mark)  # TPDO1 again

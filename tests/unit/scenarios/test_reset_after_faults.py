"""Every latched fault is resettable through the real controller once its cause is gone (SAFETY 25, issue 37 item 1).

The real simulated node and the real controller on one virtual bus. Each
case latches one fault code the way the mill meets it, takes its cause away
(the bystander stops corrupting frames, the injected fault is cleared, the
controller's heartbeat resumes, the furnace cools) and asks for a reset
through the controller, as ``millctl reset`` does: the node and the
controller come back to DISABLED without the node being restarted, and the
mill arms again. The bad-CRC burst is the case issue 37 found: the node's
E2E score healed only on good Setpoints frames, which the controller sends
only while ARMED or RUNNING, so every reset was refused ``FAULT_LATCHED``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import can
import pytest

from millctl.config import MillConfig
from millctl.controller import ControllerState as S
from millctl.protocol import EStop, FaultCode, FaultFlag, NodeState, Setpoints, SimFaultCode
from tests.unit.scenarios.rig import Rig

BURST_FRAMES = 6
"""Corrupted Setpoints frames in the burst (issue 37 item 1): one past the default E2E error limit of 5."""


def corrupted_setpoints(rig: Rig) -> can.Message:
    """A Setpoints frame whose CRC does not match its data (what a disturbed bus delivers)."""
    frame = rig.codec.encode(Setpoints(30.0, 150.0, 25.0, False), 0)
    data = bytearray(frame.data)
    data[2] ^= 0x40
    return can.Message(arbitration_id=frame.arbitration_id, data=bytes(data), is_extended_id=False)


def bad_crc_burst(rig: Rig) -> None:
    for _ in range(BURST_FRAMES):
        rig.probe.send(corrupted_setpoints(rig))


def controller_silent(rig: Rig) -> None:
    """The controller misses its ticks for longer than the node's watchdog allows (a stalled host)."""
    for _ in range(round(2.0 * rig.config.timing.watchdog_timeout_s / rig.dt_s) + 1):
        rig.node.tick()
        rig.clock.advance(rig.dt_s)


def estop(rig: Rig) -> None:
    rig.probe.send(rig.codec.encode(EStop(7)))


def injected(fault: SimFaultCode, param: float = 0.0) -> Callable[[Rig], None]:
    def inject(rig: Rig) -> None:
        rig.inject(fault, param)

    return inject


def envelope_runaway(rig: Rig) -> None:
    """The rotary drive runs away to a speed inside its own limit but outside the envelope at 150 rpm of ω_v."""
    limit_rpm = rig.node.envelope.limit_rpm(150.0)
    rig.inject(SimFaultCode.ROTARY_RUNAWAY, limit_rpm + 10.0 * rig.config.interlock.measurement_tolerance_rpm)


def heater_open(rig: Rig) -> None:
    rig.controller.set_furnace(300.0)
    rig.inject(SimFaultCode.HEATER_FAIL, 0.0)  # an open element: heating raises nothing


def heater_welded(rig: Rig) -> None:
    rig.controller.set_furnace(100.0)
    rig.inject(SimFaultCode.HEATER_FAIL, 1.0)  # a welded relay: full power whatever the node says


def furnace_unrefreshed(rig: Rig) -> None:
    """The heater is on and the whole host stalls past the furnace's refresh time; the node's next tick finds the
    heater's setpoint unrefreshed (and the heartbeat gone: WATCHDOG latches beside it)."""
    rig.controller.set_furnace(100.0)
    rig.run(0.5)
    assert rig.node.heater_on
    rig.clock.advance(rig.config.furnace.setpoint_refresh_s + 0.5)
    rig.node.tick()


CAUSES: dict[FaultCode, Callable[[Rig], None]] = {
    FaultCode.WATCHDOG: controller_silent,
    FaultCode.E2E_LINK: bad_crc_burst,
    FaultCode.ESTOP: estop,
    FaultCode.ENVELOPE: envelope_runaway,
    FaultCode.OVERSPEED: injected(SimFaultCode.ROTARY_RUNAWAY),
    FaultCode.STALL: injected(SimFaultCode.VIB_STALL),
    FaultCode.SENSOR: injected(SimFaultCode.SENSOR_NOISY),
    FaultCode.OVERTEMP: heater_welded,
    FaultCode.HEATER_VERIFY: heater_open,
    FaultCode.HEATER_TIMEOUT: furnace_unrefreshed,
}
"""How each fault the node latches is brought on while running at 30/150 rpm (DRIVE and INTERNAL: the node has
no cause that latches them)."""


FURNACE: dict[FaultCode, dict[str, float]] = {
    FaultCode.OVERTEMP: {"heat_capacity_j_per_k": 50.0},
    FaultCode.HEATER_VERIFY: {"verify_period_s": 5.0},
}
"""Furnace settings that keep the mill time short: a furnace that heats fast, a heater verified every 5 s."""


@pytest.fixture
def fault_rig(config: MillConfig, request: pytest.FixtureRequest) -> Iterator[Rig]:
    """The rig, with the furnace settings its fault code needs (``FURNACE``)."""
    furnace = config.furnace.model_copy(update=FURNACE.get(request.param, {}))
    rig = Rig(config.model_copy(update={"furnace": furnace}))
    yield rig
    rig.close()


def controller_state(rig: Rig) -> S:
    """The controller's state now (a call, so that mypy does not carry an earlier assertion's narrowing over)."""
    return rig.controller.state


def node_state(rig: Rig) -> NodeState:
    """The node's state now (as :func:`controller_state`)."""
    return rig.node.state


def reset_through_the_controller(rig: Rig) -> None:
    """Wait for standstill with the cause gone, then reset as ``millctl reset`` does; both ends DISABLED."""
    rig.inject(SimFaultCode.CLEAR)  # an injected cause is cleared by the operator (no effect otherwise)
    rig.run(30.0, until=lambda: max(rig.node.true_speeds_rpm) == 0.0)
    rig.run(1.0)
    rig.controller.reset()
    rig.run(3.0, until=lambda: rig.controller.state is S.DISABLED)
    assert rig.node.state is NodeState.DISABLED, (rig.node.state, rig.node.last_refusal, rig.node.fault_bits)
    assert rig.controller.state is S.DISABLED, rig.controller.state
    assert rig.node.fault_bits == 0
    rig.controller.arm()
    rig.run(1.0, until=lambda: rig.controller.state is S.ARMED)
    assert controller_state(rig) is S.ARMED and node_state(rig) is NodeState.ARMED


def test_six_bad_crc_setpoints_frames_trip_and_the_real_controller_resets_the_mill(rig: Rig) -> None:
    rig.start(30.0, 150.0)
    assert rig.node.state is NodeState.RUNNING
    bad_crc_burst(rig)
    rig.run(1.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert rig.controller.state is S.TRIPPED and rig.node.first_fault is FaultCode.E2E_LINK
    reset_through_the_controller(rig)


def test_a_reset_is_refused_while_bad_crc_frames_keep_coming(rig: Rig) -> None:
    """The cause is still there while the disturbance goes on: RESET stays refused, the controller says so."""
    rig.start(30.0, 150.0)
    bad_crc_burst(rig)
    rig.run(20.0, until=lambda: max(rig.node.true_speeds_rpm) == 0.0)
    rig.run(1.0)
    for tick in range(round(3.0 / rig.dt_s)):
        rig.probe.send(corrupted_setpoints(rig))  # one a tick, on and on
        rig.step()
        if tick == round(0.3 / rig.dt_s):
            rig.controller.reset()
    assert rig.node.state is NodeState.FAULT and rig.controller.state is S.TRIPPED
    assert any("reset did not complete" in event.message for event in rig.events), [e.message for e in rig.events[-8:]]


@pytest.mark.parametrize(("fault_rig", "code"), [(code, code) for code in CAUSES], ids=lambda code: code.name,
                         indirect=["fault_rig"])
def test_every_fault_code_is_cleared_by_a_reset_through_the_real_controller_once_its_cause_is_gone(
    fault_rig: Rig, code: FaultCode
) -> None:
    rig = fault_rig
    rig.start(30.0, 150.0)
    flag = FaultFlag(1 << (code - 1))
    CAUSES[code](rig)
    rig.run(300.0, until=lambda: flag in rig.node.fault_bits)
    rig.run(1.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert flag in rig.node.fault_bits, (rig.node.first_fault, rig.node.fault_bits)
    assert rig.controller.state is S.TRIPPED
    if code is FaultCode.OVERTEMP:
        rig.inject(SimFaultCode.CLEAR)
        rig.run(600.0, until=lambda: rig.node.furnace_temp_c < rig.config.furnace.over_temp_c - 5.0)
    reset_through_the_controller(rig)

"""Every command confirmed, and only what was commanded believed (issue 15 items 2 and 5, docs/safety.md).

The real simulated node and the controller on one virtual bus; the rig's probe
is the adversary: it forges commands with counters the node will take.
"""

from __future__ import annotations

import dataclasses

import pytest

from millctl.config import MillConfig
from millctl.controller import ControllerState as S
from millctl.controller import EventKind
from millctl.protocol import (
    Command,
    CommandCode,
    FaultFlag,
    MillMessage,
    NodeState,
    NodeStatus,
    RefusalCode,
    Setpoints,
)
from millctl.protocol.receive import Batch
from tests.unit.scenarios.rig import Rig


def forge(rig: Rig, message: MillMessage, counter: int) -> None:
    """Another sender puts ``message`` on the bus with the alive counter ``counter``."""
    rig.probe.send(rig.codec.encode(message, counter))


def next_counter(rig: Rig, kind: type[MillMessage]) -> int:
    """The counter the controller's next frame of ``kind`` will carry (what an eavesdropper can work out)."""
    return rig.controller._counters[kind].value


def test_a_stop_dropped_as_not_fresh_after_a_forged_disarm_is_repeated_and_the_mill_stops(
    rig: Rig, config: MillConfig
) -> None:
    """The seen defect: a forged DISARM takes the STOP's counter, the node drops the STOP as NOT_FRESH,
    and the mill kept 60/300 rpm for ≥ 20 s while the controller said STOPPING."""
    rig.start(60.0, 300.0)
    forge(rig, Command(CommandCode.DISARM), next_counter(rig, Command))
    rig.step()  # the node takes the forged frame (and refuses it: it is RUNNING)
    rig.controller.stop()
    rig.run(0.1)
    assert rig.node.last_refusal is RefusalCode.NOT_FRESH  # the operator's STOP was dropped
    assert rig.node.state is NodeState.RUNNING
    rig.run(config.interlock.command_confirm_s)  # repeated with a fresh counter, within the bound
    assert rig.node.state in (NodeState.STOPPING, NodeState.ARMED)
    rig.run(20.0, until=lambda: rig.controller.state is S.ARMED)
    assert rig.controller.state is S.ARMED  # the controlled stop completed, confirmed
    rig.run(2.0)
    assert max(rig.node.true_speeds_rpm) < 1.0


def test_a_stop_the_node_never_confirms_escalates_to_an_estop(
    rig: Rig, config: MillConfig, monkeypatch: pytest.MonkeyPatch
) -> None:
    rig.start(60.0, 300.0)
    monkeypatch.setattr(rig.node, "_stop", lambda now: RefusalCode.NONE)  # the node ignores STOP
    monkeypatch.setattr(rig.node, "_expire_setpoints", lambda now: None)  # and the setpoint expiry that stops it too
    rig.controller.stop()
    t_stop = rig.clock.now()
    rig.run(3.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert rig.controller.state is S.TRIPPED
    assert rig.clock.now() - t_stop <= config.interlock.command_confirm_s + 2 * rig.dt_s
    cause = rig.controller.trip_cause
    assert "STOP" in cause and "not confirmed" in cause and "E-stop" in cause, cause
    rig.run(0.2)
    assert FaultFlag.ESTOP in rig.node.fault_bits
    rig.run(20.0, until=lambda: max(rig.node.true_speeds_rpm) < 1.0)
    assert max(rig.node.true_speeds_rpm) < 1.0


def test_an_estop_is_repeated_until_the_node_reports_it(
    rig: Rig, config: MillConfig, monkeypatch: pytest.MonkeyPatch
) -> None:
    rig.start(60.0, 300.0)
    drain = rig.node.reader.drain
    lost_until_s = rig.clock.now() + 0.5

    def lossy_drain() -> Batch:  # the first E-stop frames never reach the node
        batch = drain()
        return dataclasses.replace(batch, estop=False) if rig.clock.now() < lost_until_s else batch

    monkeypatch.setattr(rig.node.reader, "drain", lossy_drain)
    rig.controller.estop()
    rig.run(0.4)
    assert FaultFlag.ESTOP not in rig.node.fault_bits
    rig.run(0.5)
    assert FaultFlag.ESTOP in rig.node.fault_bits  # a repeat got through
    sent = rig.controller.estops_sent
    assert sent >= 2
    rig.run(1.0)
    assert rig.controller.estops_sent == sent  # reported: no more repeats


def test_a_forged_reset_and_arm_after_an_estop_is_met_with_another_estop(rig: Rig, config: MillConfig) -> None:
    """The seen defect: a forged RESET+ARM after an E-stop restarted the mill while the controller stayed TRIPPED."""
    rig.start(120.0, 400.0)
    rig.controller.estop()
    rig.run(30.0, until=lambda: max(rig.node.true_speeds_rpm) < 0.01)
    rig.run(0.5)
    assert rig.node.state is NodeState.FAULT
    counter = next_counter(rig, Command)
    forge(rig, Command(CommandCode.RESET), counter)
    forge(rig, Command(CommandCode.ARM), (counter + 1) % 16)
    t_forged = rig.clock.now()
    setpoints_counter = next_counter(rig, Setpoints)
    for i in range(30):  # and then setpoints at the setpoint period, ramping up as fast as the node allows
        forge(rig, Setpoints(4.0 * (i + 1), 16.0 * (i + 1), 25.0, False), (setpoints_counter + i) % 16)
        rig.run(config.timing.setpoint_period_s)
    relatched = next(t for t, n in zip(rig.trace.t_s, rig.trace.node, strict=True) if t > t_forged and n == "FAULT")
    print(f"forged RESET+ARM: node back in FAULT (E-stop) after {relatched - t_forged:.3f} s")
    status_period_s = rig.codec.cycle_time_s(NodeStatus) or 0.05
    assert relatched - t_forged <= status_period_s + 3 * rig.dt_s  # one NodeStatus, then the E-stop
    rig.run(2.0)
    assert rig.controller.state is S.TRIPPED
    assert rig.node.state is NodeState.FAULT and FaultFlag.ESTOP in rig.node.fault_bits
    peak = max(max(w) for w in rig.trace.true[-500:])
    assert peak < 20.0, peak  # one forged step's worth, not the 120/480 rpm the forger asked for
    assert max(rig.node.true_speeds_rpm) < 0.1  # and back at rest
    estops = [e for e in rig.events if e.kind is EventKind.TRIP and e.message.startswith("E-stop:")]
    assert any("did not command" in e.message for e in estops), [e.message for e in estops]


def test_the_measured_speed_is_checked_in_tripped(rig: Rig, config: MillConfig) -> None:
    """A drive that speeds up while the controller is TRIPPED is an E-stop (the check runs in every state)."""
    from millctl.protocol import SimFaultCode

    rig.start(0.0, 0.0)
    rig.controller.estop()
    rig.run(0.5)
    before = rig.controller.estops_sent
    rig.inject(SimFaultCode.ROTARY_RUNAWAY, 120.0)  # the rotor runs away whatever it is told
    rig.run(3.0, until=lambda: rig.controller.estops_sent > before)
    assert rig.controller.estops_sent > before
    (event,) = [e for e in rig.events if e.kind is EventKind.TRIP and "stop ceiling" in e.message][:1]
    assert "measured ω_r" in event.message


def test_a_forged_setpoint_that_moves_a_disabled_mill_trips(rig: Rig) -> None:
    rig.start(0.0, 0.0)  # ARMED at standstill, nothing commanded
    forge(rig, Setpoints(3.0, 12.0, 25.0, False), next_counter(rig, Setpoints))  # a step the node accepts
    rig.run(1.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert rig.controller.state is S.TRIPPED
    assert "ARMED → RUNNING" in rig.controller.trip_cause and "did not command" in rig.controller.trip_cause

"""A second sender on a protected identifier faults the link on both sides (SAFETY 17, issue 15 item 3).

The bystander bus answers every genuine frame with a forged one carrying
counter + 1 and "all well" content: the forgery is accepted as fresh (OK) and
the genuine frame that follows is REPEATED. Under the old net error score
alone the two cancelled out for ever, and the controller believed the forger.
"""

from __future__ import annotations

from millctl.controller import ControllerState as S
from millctl.protocol import (
    NO_FAULTS,
    AliveCounter,
    ControllerState,
    DriveTelemetry,
    FaultCode,
    FaultFlag,
    Heartbeat,
    MillMessage,
    NodeState,
    NodeStatus,
    ProtocolError,
    RefusalCode,
    SimFaultCode,
)
from tests.unit.scenarios.rig import Rig

LOW_RPM = (60.0, 300.0)
ALL_WELL: dict[type[MillMessage], MillMessage] = {
    NodeStatus: NodeStatus(NodeState.RUNNING, NO_FAULTS, FaultCode.NONE, 0, RefusalCode.NONE),
    DriveTelemetry: DriveTelemetry(*LOW_RPM, 0.1, 0.1),
}


def forge_answers(rig: Rig, kinds: tuple[type[MillMessage], ...]) -> int:
    """Read what the bystander heard; answer each genuine frame of ``kinds`` with counter + 1. Returns how many."""
    sent = 0
    for frame in iter(lambda: rig.probe.recv(timeout=0.0), None):
        try:
            decoded = rig.codec.decode(frame)
        except ProtocolError:
            continue
        if decoded.kind in kinds and decoded.crc_ok and decoded.counter is not None:
            forged = ALL_WELL.get(decoded.kind) or Heartbeat(ControllerState.RUNNING)
            rig.probe.send(rig.codec.encode(forged, (decoded.counter + 1) % 16))
            sent += 1
    return sent


def test_a_forger_answering_every_node_frame_trips_the_controller_whatever_the_node_does(rig: Rig) -> None:
    rig.start(*LOW_RPM)
    rig.inject(SimFaultCode.ROTARY_RUNAWAY)  # the node faults; the forger says RUNNING, 60 rpm, no faults
    forged, t_first = 0, rig.clock.now()
    for _ in range(round(2.0 / rig.dt_s)):
        rig.node.tick()
        rig.controller.tick()
        forged += forge_answers(rig, (NodeStatus, DriveTelemetry))
        rig.clock.advance(rig.dt_s)
        if rig.controller.state is S.TRIPPED:
            break
    assert rig.controller.state is S.TRIPPED, "the controller believed the forger"
    assert rig.clock.now() - t_first < 0.5 and forged > 0
    assert "E2E sequence score" in rig.controller.trip_cause and "second sender" in rig.controller.trip_cause
    health = rig.controller.status().link
    assert max(int(str(h["e2e_sequence_score"])) for h in health.values()) >= rig.config.interlock.e2e_error_limit


def test_a_second_heartbeat_sender_faults_the_nodes_link(rig: Rig) -> None:
    rig.start(*LOW_RPM)
    for _ in range(round(2.0 / rig.dt_s)):
        rig.controller.tick()
        forge_answers(rig, (Heartbeat,))
        rig.node.tick()
        rig.clock.advance(rig.dt_s)
        if rig.node.state is NodeState.FAULT:
            break
    assert rig.node.state is NodeState.FAULT
    assert FaultFlag.E2E_LINK in rig.node.fault_bits and rig.node.first_fault is FaultCode.E2E_LINK
    assert rig.node.link.receivers[Heartbeat].sequence_score >= rig.config.interlock.e2e_error_limit
    rig.run(2.0, until=lambda: rig.controller.state is S.TRIPPED)
    assert "E2E_LINK" in rig.controller.trip_cause


def test_a_forger_out_sending_the_node_cannot_pay_back_the_errors_its_interleaving_makes(rig: Rig) -> None:
    """An "all well" NodeStatus at 1000 frames/s beside the node's 20, on counters of its own. Each genuine frame
    makes a sequence error or two; counted in frames alone, the forger's next 32 fresh frames forgave them, the
    link never faulted, and the controller echoed the forger's challenges until the node's watchdog stopped the
    mill, under the wrong name. Forgiven no faster than the node sends (``E2EReceiver.min_decay_s``), the
    interleaving trips the controller within a few genuine frames, naming a second sender."""
    rig.start(*LOW_RPM)
    forged, started_s = AliveCounter(start=9), rig.clock.now()
    for _ in range(round(1.0 / rig.dt_s)):
        for _ in range(10):
            rig.probe.send(rig.codec.encode(ALL_WELL[NodeStatus], forged.next()))
        rig.node.tick()
        rig.controller.tick()
        for _ in iter(lambda: rig.probe.recv(timeout=0.0), None):
            pass
        rig.clock.advance(rig.dt_s)
        if rig.controller.state is S.TRIPPED:
            break
    assert rig.controller.state is S.TRIPPED, "the controller believed the forger"
    assert rig.clock.now() - started_s < 0.5
    assert "NodeStatus E2E sequence score" in rig.controller.trip_cause
    assert "second sender" in rig.controller.trip_cause

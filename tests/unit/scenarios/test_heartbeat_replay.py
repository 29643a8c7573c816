"""Replayed heartbeats cannot keep the mill running after the controller died (SAFETY 16, issue 15 item 4).

The bystander records the controller's heartbeats off the bus (16 of them: a
whole turn of the 4-bit alive counter, so the loop passes the E2E sequence
check), the controller's loop stops, and the bystander replays the recording
in a loop at the heartbeat rate. Each recorded heartbeat echoes a NodeStatus
challenge that has since been superseded or has expired, so none of them
feeds the node's watchdog and the mill stops.
"""

from __future__ import annotations

import can

from millctl.protocol import FaultCode, FaultFlag, Heartbeat, NodeState, ProtocolError
from tests.unit.scenarios.rig import Rig

LOW_RPM = (60.0, 300.0)
RECORDED = 16


def heartbeats_heard(rig: Rig) -> list[can.Message]:
    heard = []
    for frame in iter(lambda: rig.probe.recv(timeout=0.0), None):
        try:
            if rig.codec.decode(frame).kind is Heartbeat:
                heard.append(frame)
        except ProtocolError:
            continue
    return heard


def record_heartbeats(rig: Rig) -> list[can.Message]:
    """Step node and controller (the bystander listening) until it has heard ``RECORDED`` heartbeats."""
    recording: list[can.Message] = []
    while len(recording) < RECORDED:
        rig.node.tick()
        rig.controller.tick()
        recording += heartbeats_heard(rig)
        rig.clock.advance(rig.dt_s)
    return recording[:RECORDED]


def replay_after_controller_death(rig: Rig, recording: list[can.Message], seconds: float) -> tuple[float, int]:
    """Stop the controller, replay ``recording`` in a loop at the heartbeat period; (time to FAULT, fresh fed)."""
    period_s = rig.config.timing.heartbeat_period_s
    t_dead = rig.clock.now()
    rig.node.tick()  # the controller's last genuine heartbeat, still on the bus
    rig.clock.advance(rig.dt_s)
    fed_before, next_s, k = rig.node.link.fresh_heartbeats, rig.clock.now(), 0
    while rig.clock.now() - t_dead < seconds and rig.node.state is not NodeState.FAULT:
        if rig.clock.now() >= next_s - 1e-9:
            rig.probe.send(recording[k % len(recording)])
            k, next_s = k + 1, next_s + period_s
        rig.node.tick()
        rig.clock.advance(rig.dt_s)
    return rig.clock.now() - t_dead, rig.node.link.fresh_heartbeats - fed_before


def test_heartbeats_recorded_earlier_and_replayed_after_the_controller_died_feed_nothing(rig: Rig) -> None:
    rig.start(*LOW_RPM)
    recording = record_heartbeats(rig)
    rig.run(2.0)  # the recording ages
    elapsed_s, fed = replay_after_controller_death(rig, recording, 10.0)
    timing = rig.config.timing
    assert fed == 0
    assert rig.node.state is NodeState.FAULT and rig.node.first_fault is FaultCode.WATCHDOG
    assert elapsed_s <= timing.watchdog_timeout_s + 2 * timing.node_tick_s
    assert rig.node.link.expired_echoes > 0
    rig.run(20.0, until=lambda: max(rig.node.true_speeds_rpm) < 1.0)
    assert max(rig.node.true_speeds_rpm) < 1.0 and not rig.node.heater_on


def test_heartbeats_recorded_up_to_the_controllers_death_stop_feeding_within_the_challenge_lifetime(
    rig: Rig,
) -> None:
    rig.start(*LOW_RPM)
    recording = record_heartbeats(rig)  # the newest of them echo the challenge in play when the controller dies
    elapsed_s, fed = replay_after_controller_death(rig, recording, 10.0)
    timing = rig.config.timing
    assert FaultFlag.WATCHDOG in rig.node.fault_bits
    assert fed <= 2  # at most the recording's last heartbeats, echoing the challenge still in play
    assert elapsed_s <= timing.challenge_lifetime_s + timing.watchdog_timeout_s + 2 * timing.node_tick_s

"""A heartbeat forger cannot keep a controller-less mill running: setpoints expire at the node (SAFETY 26, issue 37
item 6).

The controller's loop stops mid-run; from the next heartbeat period a forger
on the bus keeps the node's watchdog fed as well as anyone can: it listens to
every NodeStatus, echoes its latest challenge and continues the controller's
alive counter, so every forged heartbeat is fresh. It sends no Setpoints. The
node, which accepted no drive setpoint for ``timing.setpoint_expiry_s``, stops
the drives in a controlled way: the mill comes to rest although the watchdog
never fires.
"""

from __future__ import annotations

from millctl.protocol import (
    ControllerState,
    Decoded,
    FaultFlag,
    Heartbeat,
    NodeState,
    NodeStatus,
    ProtocolError,
)
from tests.unit.scenarios.rig import Rig

RUN_RPM = (30.0, 150.0)


class HeartbeatForger:
    """Echoes the latest challenge it heard, with the alive counter that follows the last heartbeat it heard."""

    def __init__(self, rig: Rig) -> None:
        self.rig = rig
        self.challenge: int | None = None
        self.counter = 0
        self.sent = 0

    def listen(self) -> None:
        for frame in iter(lambda: self.rig.probe.recv(timeout=0.0), None):
            try:
                decoded: Decoded = self.rig.codec.decode(frame)
            except ProtocolError:
                continue
            if isinstance(decoded.message, NodeStatus):
                self.challenge = decoded.message.challenge
            elif isinstance(decoded.message, Heartbeat) and decoded.counter is not None:
                self.counter = (decoded.counter + 1) % 16

    def send(self) -> None:
        assert self.challenge is not None, "the forger heard no NodeStatus"  # the caller waits for one
        heartbeat = Heartbeat(ControllerState.RUNNING, self.challenge)
        self.rig.probe.send(self.rig.codec.encode(heartbeat, self.counter))
        self.counter = (self.counter + 1) % 16
        self.sent += 1


def node_state(rig: Rig) -> NodeState:
    """The node's state now (a call, so that mypy does not carry an earlier assertion's narrowing over)."""
    return rig.node.state


def test_a_live_heartbeat_forger_with_a_silent_controller_stops_the_drives_within_the_setpoint_expiry(
    rig: Rig,
) -> None:
    timing = rig.config.timing
    expiry_s = timing.setpoint_expiry_s
    assert expiry_s == max(timing.setpoint_expiry_periods * timing.setpoint_period_s, timing.min_setpoint_expiry_s)
    rig.start(*RUN_RPM)
    assert rig.node.state is NodeState.RUNNING
    forger = HeartbeatForger(rig)
    fed_before = rig.node.link.fresh_heartbeats
    period_ticks = round(timing.heartbeat_period_s / rig.dt_s)
    t_silent = rig.clock.now()
    stopping_at: float | None = None
    for tick in range(round((expiry_s + 15.0) / rig.dt_s)):  # the controller ticks no more from here
        rig.node.tick()
        forger.listen()
        if tick % period_ticks == 0 and forger.challenge is not None:
            forger.send()
        rig.clock.advance(rig.dt_s)
        if stopping_at is None and rig.node.state is not NodeState.RUNNING:
            stopping_at = rig.clock.now()
    assert rig.node.link.fresh_heartbeats - fed_before >= forger.sent - 2  # the forgery fed the watchdog throughout
    assert forger.sent > 0 and FaultFlag.WATCHDOG not in rig.node.fault_bits
    assert stopping_at is not None, "the drives kept running on forged heartbeats alone"
    assert stopping_at - t_silent <= expiry_s + timing.setpoint_period_s + 2 * rig.dt_s
    assert rig.node.setpoints_expired == 1
    assert rig.node.true_speeds_rpm == (0.0, 0.0)
    assert node_state(rig) is NodeState.ARMED  # stopped and at rest, never RUNNING again without a setpoint


def test_a_controller_that_keeps_sending_holds_the_speeds_past_the_expiry(rig: Rig) -> None:
    rig.start(*RUN_RPM)
    rig.run(5.0 * rig.config.timing.setpoint_expiry_s)
    assert rig.node.state is NodeState.RUNNING and rig.node.setpoints_expired == 0
    assert min(rig.node.measured_speeds_rpm) > 0.0

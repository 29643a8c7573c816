"""A stepped bench for the simulated node: a fake controller on a private python-can virtual channel."""

from __future__ import annotations

import contextlib
import uuid
from collections.abc import Callable, Iterator
from typing import Any

import can
import pytest

from firmware_sim.node import Node
from firmware_sim.telemetry import PhysicsWorker
from millctl.clock import ManualClock
from millctl.config import MillConfig
from millctl.protocol import (
    AliveCounter,
    Command,
    CommandCode,
    ControllerState,
    Decoded,
    Heartbeat,
    MillMessage,
    NodeStatus,
    ProtocolError,
    Setpoints,
    SimFault,
    SimFaultCode,
    default_codec,
)
from millctl.safety import Envelope, RampPlanner, SpeedPoint, Trajectory


class Bench:
    """The node under test and a controller stand-in that sends heartbeats, commands and setpoints."""

    def __init__(
        self,
        config: MillConfig,
        *,
        fault_injection: bool = False,
        seed: int = 0,
        physics_worker: PhysicsWorker = "inline",
    ) -> None:
        self.config = config
        self.channel = f"node-test-{uuid.uuid4().hex}"
        self.node_bus = can.Bus(interface="virtual", channel=self.channel, receive_own_messages=False)
        self.ctl_bus = can.Bus(interface="virtual", channel=self.channel, receive_own_messages=False)
        self.clock = ManualClock(100.0)
        self.node = Node(
            config, self.node_bus, self.clock, fault_injection=fault_injection, seed=seed, physics_worker=physics_worker
        )
        self.codec = default_codec()
        self.envelope = Envelope.from_config(config)
        self.counters: dict[type[MillMessage], AliveCounter] = {
            Command: AliveCounter(),
            Heartbeat: AliveCounter(),
            Setpoints: AliveCounter(),
        }
        self.heartbeat_period_s = config.timing.heartbeat_period_s
        self.tick_s = 2.0 * config.timing.node_tick_s
        """How far one bench step moves the clock (s); the node sub-steps its physics at its configured tick."""
        self._next_heartbeat_s = self.clock.now()
        self._next_setpoint_s = self.clock.now()
        self.point = SpeedPoint(0.0, 0.0)
        self.hold: Setpoints | None = None
        """Setpoints re-sent every setpoint period (the controller's refresh), if any."""
        self.move: tuple[Trajectory, float, float, bool] | None = None
        self.received: list[Decoded] = []
        self.frame_ids: list[int] = []
        """Identifiers of every frame the node sent, decodable or not."""
        self.on_tick: list[Callable[[Bench], None]] = []

    # -- sending ---------------------------------------------------------------------------

    def send(self, message: MillMessage, counter: int | None = None) -> None:
        """Send as the controller; E2E messages take the next alive counter unless one is given."""
        if counter is None:
            alive = self.counters.get(type(message))
            counter = alive.next() if alive is not None else 0
        self.ctl_bus.send(self.codec.encode(message, counter))

    def heartbeat(self) -> None:
        """A heartbeat as the controller sends it: echoing the challenge of the latest NodeStatus received."""
        self.send(Heartbeat(ControllerState.RUNNING, self.challenge()))

    def challenge(self) -> int:
        """The challenge of the latest NodeStatus received (0 before the first)."""
        for decoded in reversed(self.received):
            if isinstance(decoded.message, NodeStatus):
                return decoded.message.challenge
        return 0

    def command(self, code: CommandCode) -> None:
        self.send(Command(code))

    def setpoints(self, rotary_rpm: float, vibration_rpm: float, furnace_c: float = 25.0, heater: bool = False) -> None:
        self.send(Setpoints(round(rotary_rpm, 1), round(vibration_rpm, 1), furnace_c, heater))

    def inject(self, fault: SimFaultCode, param: float = 0.0, active: bool = True) -> None:
        self.send(SimFault(fault, active, param))

    # -- stepping ---------------------------------------------------------------------------

    def step(self, duration_s: float, *, heartbeat: bool = True, dt_s: float | None = None) -> None:
        """Run the node for ``duration_s`` with heartbeats (unless told not to) and the held setpoints."""
        dt = self.tick_s if dt_s is None else dt_s
        for _ in range(max(1, round(duration_s / dt))):
            now = self.clock.advance(dt)
            if heartbeat and now >= self._next_heartbeat_s - 1e-9:
                self.heartbeat()
                self._next_heartbeat_s = now + self.heartbeat_period_s
            if now >= self._next_setpoint_s - 1e-9:
                self._refresh(now)
                self._next_setpoint_s = now + self.config.timing.setpoint_period_s
            self.node.tick()
            self.collect()
            for hook in self.on_tick:
                hook(self)

    def _refresh(self, now: float) -> None:
        if self.move is not None:
            trajectory, started, furnace_c, heater = self.move
            point = trajectory.at(now - started)
            self.setpoints(point.omega_r_rpm, point.omega_v_rpm, furnace_c, heater)
            if now - started > trajectory.duration_s:
                self.move = None
                self.hold = Setpoints(round(point.omega_r_rpm, 1), round(point.omega_v_rpm, 1), furnace_c, heater)
        elif self.hold is not None:
            self.send(self.hold)

    def collect(self) -> None:
        while (frame := self.ctl_bus.recv(timeout=0)) is not None:
            self.frame_ids.append(frame.arbitration_id)
            with contextlib.suppress(ProtocolError):
                self.received.append(self.codec.decode(frame))

    def latest(self, kind: type[MillMessage]) -> Any:
        for decoded in reversed(self.received):
            if decoded.kind is kind and decoded.message is not None:
                return decoded.message
        raise AssertionError(f"no {kind.__name__} received")

    # -- procedures -------------------------------------------------------------------------

    def arm(self) -> None:
        self.point = SpeedPoint(0.0, 0.0)
        self.step(0.1)
        self.heartbeat()  # echoing a challenge the node has issued by now, whatever the heartbeat period
        self._next_heartbeat_s = self.clock.now() + self.heartbeat_period_s
        self.command(CommandCode.ARM)
        self.step(self.tick_s)

    def ramp_to(self, rotary_rpm: float, vibration_rpm: float, furnace_c: float = 25.0, heater: bool = False) -> None:
        """Ramp as the controller would (planned, sampled every setpoint period) and settle there."""
        trajectory = RampPlanner(self.envelope).plan(self.point, SpeedPoint(rotary_rpm, vibration_rpm))
        self.point = trajectory.end
        self.hold = None
        self.move = (trajectory, self.clock.now() + 1e-9, furnace_c, heater)
        self._next_setpoint_s = self.clock.now()
        self.step(trajectory.duration_s + 1.5)

    def run_at(self, rotary_rpm: float, vibration_rpm: float) -> None:
        """ARM and ramp to an operating point."""
        self.arm()
        self.ramp_to(rotary_rpm, vibration_rpm)

    def close(self) -> None:
        self.node.close()
        self.node_bus.shutdown()
        self.ctl_bus.shutdown()


@pytest.fixture
def make_bench(config: MillConfig) -> Iterator[Callable[..., Bench]]:
    """Build benches (default config unless given); their buses are shut down after the test."""
    benches: list[Bench] = []

    def make(cfg: MillConfig | None = None, **kwargs: Any) -> Bench:
        bench = Bench(cfg or config, **kwargs)
        benches.append(bench)
        return bench

    yield make
    for bench in benches:
        bench.close()


@pytest.fixture
def bench(make_bench: Callable[..., Bench]) -> Bench:
    return make_bench()


__all__ = ["Bench", "NodeStatus"]

"""The in-process rig: the real simulated node and the controller on one virtual bus, one stepped clock.

A third bus (``probe``) is a bystander: it injects faults, sends E-stops or
rogue frames, and watches the traffic. Nothing sleeps; a minute of mill time
takes well under a second of CPU.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable
from dataclasses import dataclass, field

import can

from firmware_sim.node import Node
from millctl.clock import ManualClock
from millctl.config import MillConfig
from millctl.controller import Controller, Event
from millctl.protocol import SimFault, SimFaultCode, default_codec


@dataclass
class Trace:
    """What happened at each step: time, controller state, node state, measured and true speeds."""

    t_s: list[float] = field(default_factory=list)
    controller: list[str] = field(default_factory=list)
    node: list[str] = field(default_factory=list)
    measured: list[tuple[float, float]] = field(default_factory=list)
    true: list[tuple[float, float]] = field(default_factory=list)


class Rig:
    """Node + controller + a bystander, stepped together at the node's tick."""

    def __init__(
        self,
        config: MillConfig,
        *,
        fault_injection: bool = True,
        seed: int = 0,
        controller_bus: Callable[[str], can.BusABC] | None = None,
    ) -> None:
        """``controller_bus`` opens the controller's bus on the rig's channel (default: a virtual bus)."""
        channel = f"rig-{uuid.uuid4().hex}"
        self.config = config
        self.dt_s = config.timing.node_tick_s
        self.clock = ManualClock()
        self.codec = default_codec()
        self.events: list[Event] = []
        self._buses = [can.Bus(interface="virtual", channel=channel) for _ in range(3)]
        if controller_bus is not None:
            self._buses[1].shutdown()
            self._buses[1] = controller_bus(channel)
        node_bus, controllers_bus, self.probe = self._buses
        self.node = Node(config, node_bus, self.clock, fault_injection=fault_injection, seed=seed)
        self.controller = Controller(config, controllers_bus, self.clock, listener=self.events.append)
        self.trace = Trace()
        self.node_alive = True

    def close(self) -> None:
        self.node.close()
        for bus in self._buses:
            bus.shutdown()

    def step(self) -> None:
        if self.node_alive:
            self.node.tick()
        self.controller.tick()
        for _ in iter(lambda: self.probe.recv(timeout=0.0), None):
            pass
        t = self.trace
        t.t_s.append(self.clock.now())
        t.controller.append(str(self.controller.state))
        t.node.append(self.node.state.name)
        t.measured.append(self.node.measured_speeds_rpm)
        t.true.append(self.node.true_speeds_rpm)
        self.clock.advance(self.dt_s)

    def run(self, seconds: float, until: Callable[[], bool] | None = None) -> float:
        """Step for up to ``seconds``; stop early when ``until()`` holds. Returns the elapsed time (s)."""
        start = self.clock.now()
        for _ in range(round(seconds / self.dt_s)):
            if until is not None and until():
                break
            self.step()
        return self.clock.now() - start

    def inject(self, fault: SimFaultCode, param: float = 0.0, active: bool = True) -> None:
        self.probe.send(self.codec.encode(SimFault(fault, active, param)))

    def start(self, rotary_rpm: float, vibration_rpm: float) -> float:
        """Connect, arm and ramp to a speed pair; return the move's planned duration (s)."""
        from millctl.controller import ControllerState as S

        self.run(1.0, until=lambda: self.controller.state is S.DISABLED)
        self.controller.arm()
        self.run(1.0, until=lambda: self.controller.state is S.ARMED)
        move = self.controller.set_speeds(rotary_rpm, vibration_rpm)
        self.run(move.duration_s + 2.0)
        return move.duration_s

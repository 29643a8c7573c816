"""The in-process rig over either drive backend: the controller and the simulated mill of ``[drives] backend``.

``millbus``: the simulated node (firmware_sim.node); ``cia402``: the simulated
CiA 402 drives (firmware_sim.cia402), rotary node 2 and vibration node 3, the
controller node 1. Both on one virtual bus with a bystander (``probe``) that
injects faults, stepped together by one manual clock. The scenarios judge
what a user relies on through the controller and the rotors' true speeds,
the same on both backends (issue 36 part 5).
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Callable

import can

from firmware_sim.cia402 import Cia402Mill, PowerState
from firmware_sim.cia402.furnace_mill import Cia402FurnaceMill
from firmware_sim.embedded import simulated_mill
from firmware_sim.node import Node
from millctl.clock import ManualClock
from millctl.config import MillConfig
from millctl.controller import Controller, ControllerState, Event
from millctl.protocol import NodeState, SimFault, SimFaultCode, default_codec

BACKENDS = ("millbus", "cia402")
CONFIGS = {"millbus": "config/mill.toml", "cia402": "config/mill-cia402.toml"}
"""The shipped configuration of each backend (the same mill, parameter Set A)."""

STOPPED_BY_THE_DRIVES = frozenset({PowerState.QUICK_STOP_ACTIVE, PowerState.SWITCH_ON_DISABLED,
                                   PowerState.FAULT_REACTION_ACTIVE, PowerState.FAULT})
"""CiA 402 states in which a drive no longer follows the controller's target (stopping or stopped)."""


class BackendRig:
    """Controller + simulated mill + bystander on one virtual bus, stepped at the mill's tick (times in s)."""

    def __init__(self, config: MillConfig, *, fault_injection: bool = True) -> None:
        channel = f"rig-{uuid.uuid4().hex}"
        self.config = config
        self.dt_s = config.timing.node_tick_s
        self.clock = ManualClock()
        self.codec = default_codec()
        self.events: list[Event] = []
        self._buses = [can.Bus(interface="virtual", channel=channel) for _ in range(3)]
        mill_bus, controller_bus, self.probe = self._buses
        self.sim: Node | Cia402Mill | Cia402FurnaceMill = simulated_mill(
            config, mill_bus, self.clock, fault_injection=fault_injection)
        self.controller = Controller(config, controller_bus, self.clock, listener=self.events.append)
        self.true: list[tuple[float, float]] = []
        self.t_s: list[float] = []
        self.controller_alive = True

    def close(self) -> None:
        self.controller.drives.close()
        self.sim.close()
        for bus in self._buses:
            bus.shutdown()

    def step(self) -> None:
        self.sim.tick()
        if self.controller_alive:
            self.controller.tick()
        for _ in iter(lambda: self.probe.recv(timeout=0.0), None):
            pass
        self.t_s.append(self.clock.now())
        self.true.append(self.sim.true_speeds_rpm)
        self.clock.advance(self.dt_s)
        time.sleep(0)  # the CiA 402 backend's SDO worker takes the answer this tick delivered

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
        S = ControllerState
        self.run(30.0, until=lambda: self.controller.state is S.DISABLED)
        assert self.state() is S.DISABLED, self.controller.trip_cause
        self.controller.arm()
        self.run(30.0, until=lambda: self.controller.state is S.ARMED)
        assert self.state() is S.ARMED, self.controller.trip_cause
        move = self.controller.set_speeds(rotary_rpm, vibration_rpm)

        def there() -> bool:
            w_r, w_v = self.sim.true_speeds_rpm
            return abs(w_r - rotary_rpm) < 0.5 and abs(w_v - vibration_rpm) < 0.5

        # CiA 402: the move waits at its start until the drives hold its limits (SDO on the backend's worker,
        # which takes a number of ticks that depends on the host's load, not the mill's clock)
        self.run(move.duration_s + 30.0, until=there)
        self.run(1.0)
        return move.duration_s

    def state(self) -> ControllerState:
        """The controller's state now (a call, so that a check after a step is not narrowed away)."""
        return self.controller.state

    @property
    def at_rest(self) -> bool:
        """Both rotors (true speed) below 1 rpm."""
        return max(self.sim.true_speeds_rpm) < 1.0

    def stopped_by_the_mill(self) -> bool:
        """The mill's own protection has taken over: the node in FAULT, or every drive stopping or stopped."""
        sim = self.sim
        if isinstance(sim, Node):
            return sim.state is NodeState.FAULT
        return all(d.state in STOPPED_BY_THE_DRIVES for d in sim.drives.values())

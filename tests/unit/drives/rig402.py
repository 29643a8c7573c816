"""The controller on the CiA 402 backend against the simulated CiA 402 drives, with a bystander, one manual clock."""

from __future__ import annotations

import time
import uuid
from collections.abc import Callable

import can

from firmware_sim.cia402 import Cia402Mill
from millctl.clock import ManualClock
from millctl.config import MillConfig, load_config
from millctl.controller import Controller, ControllerState, Event

CONFIG = "config/mill-cia402.toml"

S = ControllerState


class Rig402:
    """Controller + simulated drives + probe on one virtual bus (times in s, the manual clock's)."""

    def __init__(self, config: MillConfig | None = None) -> None:
        channel = f"rig402-{uuid.uuid4().hex}"
        self.config = config or load_config(CONFIG).config
        self.clock = ManualClock()
        self.events: list[Event] = []
        self.buses = [can.Bus(interface="virtual", channel=channel) for _ in range(3)]
        mill_bus, controller_bus, self.probe = self.buses
        self.sim = Cia402Mill(self.config, mill_bus, self.clock)
        self.controller = Controller(self.config, controller_bus, self.clock, listener=self.events.append)
        self.heard: list[can.Message] = []

    def close(self) -> None:
        self.controller.drives.close()
        self.sim.close()
        for bus in self.buses:
            bus.shutdown()

    def step(self) -> None:
        self.controller.tick()
        self.sim.tick()
        self.heard.extend(iter(lambda: self.probe.recv(timeout=0.0), None))
        self.clock.advance(self.config.timing.controller_tick_s)
        time.sleep(0)  # let the SDO worker take the answer the tick delivered

    def run(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        """Step for up to ``seconds`` (simulated); True as soon as ``until()`` holds."""
        for _ in range(round(seconds / self.config.timing.controller_tick_s)):
            if until is not None and until():
                return True
            self.step()
        return until() if until is not None else True

    def connect(self) -> None:
        assert self.run(30.0, lambda: self.controller.state is S.DISABLED), self.controller.trip_cause

    def arm(self) -> None:
        self.connect()
        self.controller.arm()
        assert self.run(30.0, lambda: self.controller.state is S.ARMED), self.controller.trip_cause

    def messages(self, kind: str) -> list[str]:
        return [e.message for e in self.events if e.kind == kind]

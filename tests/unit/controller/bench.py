"""A scripted stand-in for the node: talks raw frames to one Controller on a virtual bus."""

from __future__ import annotations

import itertools
import uuid
from typing import TypeVar

import can

from millctl.clock import ManualClock
from millctl.config import MillConfig
from millctl.controller import Controller, ControllerState, Event, EventKind
from millctl.protocol import (
    AliveCounter,
    Decoded,
    DriveTelemetry,
    FurnaceTelemetry,
    MillMessage,
    NodeState,
    NodeStatus,
    Setpoints,
    default_codec,
)

M = TypeVar("M", bound=MillMessage)


class ScriptedNode:
    """Sends node frames by hand and collects what the controller sends."""

    def __init__(self, config: MillConfig) -> None:
        channel = f"test-{uuid.uuid4().hex}"
        self.clock = ManualClock()
        self.codec = default_codec()
        self.events: list[Event] = []
        self.controller_bus = can.Bus(interface="virtual", channel=channel)
        self.bus = can.Bus(interface="virtual", channel=channel)
        self.controller = Controller(config, self.controller_bus, self.clock, listener=self.events.append)
        self.counters: dict[type[MillMessage], AliveCounter] = {}
        self.sent: list[tuple[float, Decoded]] = []

    def close(self) -> None:
        self.controller_bus.shutdown()
        self.bus.shutdown()

    def say(self, message: MillMessage) -> None:
        counter = self.counters.setdefault(type(message), AliveCounter()).next() if message.E2E else 0
        self.bus.send(self.codec.encode(message, counter))

    def alive(
        self,
        state: NodeState = NodeState.DISABLED,
        rotary_rpm: float = 0.0,
        vibration_rpm: float = 0.0,
        setpoint_c: float = 25.0,
        heater_on: bool = False,
    ) -> None:
        """One round of the node's safety-relevant frames."""
        self.say(NodeStatus(state))
        self.say(DriveTelemetry(rotary_rpm, vibration_rpm))
        self.say(FurnaceTelemetry(25.0, setpoint_c, 0.0, heater_on))

    def collect(self) -> None:
        for frame in iter(lambda: self.bus.recv(timeout=0.0), None):
            self.sent.append((self.clock.now(), self.codec.decode(frame)))

    def followed(self) -> dict[str, object]:
        """A node that did what it was told: the last setpoint as its speeds and heater, RUNNING while it is not
        zero."""
        sent = self.messages(Setpoints)
        last = sent[-1] if sent else Setpoints(0.0, 0.0, 25.0, False)
        moving = last.rotary_rpm > 0.0 or last.vibration_rpm > 0.0
        return {"state": NodeState.RUNNING if moving else NodeState.ARMED, "rotary_rpm": last.rotary_rpm,
                "vibration_rpm": last.vibration_rpm, "setpoint_c": last.furnace_c, "heater_on": last.heater_on}

    def run(self, seconds: float, dt: float = 0.01, *, follow: bool = False, **alive: object) -> None:
        """Tick the controller for ``seconds``; with ``alive`` kwargs, the node talks every 50 ms.

        With ``follow``, the node reports the last setpoint as its speeds (and RUNNING while it is not zero).
        """
        steps = round(seconds / dt)
        for i in itertools.count():
            if i >= steps:
                break
            if follow and i % 5 == 0:
                self.alive(**self.followed())  # type: ignore[arg-type]
            elif alive and i % 5 == 0:
                self.alive(**alive)  # type: ignore[arg-type]
            self.controller.tick()
            self.collect()
            self.clock.advance(dt)

    def armed(self, source: str = "operator") -> None:
        """From a node just seen DISABLED to ARMED: ``source`` arms, the node reports ARMED."""
        self.run(0.2, state=NodeState.DISABLED)
        self.controller.arm(source)
        self.run(0.2, state=NodeState.ARMED)
        assert self.controller.state is ControllerState.ARMED

    def last_event(self, kind: EventKind) -> Event:
        """The controller's latest event of ``kind``."""
        return [e for e in self.events if e.kind is kind][-1]

    def of(self, kind: type[MillMessage]) -> list[tuple[float, Decoded]]:
        return [(t, d) for t, d in self.sent if d.kind is kind]

    def messages(self, kind: type[M]) -> list[M]:
        """The messages of ``kind`` the controller sent, in order (each must have decoded whole)."""
        found = [d.message for _, d in self.sent if d.kind is kind]
        assert all(isinstance(m, kind) for m in found), f"a {kind.__name__} frame the controller sent did not decode"
        return [m for m in found if isinstance(m, kind)]

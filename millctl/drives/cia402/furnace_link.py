"""The millbus furnace node beside the CiA 402 drives, on a CAN channel of its own (``[drives.furnace_bus]``).

Why a second channel rather than the drives' bus: millbus's E-stop (0x000) is
CANopen's NMT identifier and its NodeStatus (0x100) CANopen's TIME object, so
the millbus node cannot share a CANopen bus as it is; on its own channel its
wire stays exactly the millbus one (``config/millbus.dbc``: E2E counter and
CRC on every frame, the heartbeat's challenge, the E-stop at 0x000) and
nothing clashes (docs/deployment.md, "A furnace beside the drives: a second
CAN channel"). :class:`FurnaceLink` sends the controller's frames there with
their alive counters, checks the node's frames with E2E as the controller does
on millbus, and keeps the furnace node's last NodeStatus, which the drives'
report (:mod:`.report`) merges into the one node the controller judges; its
FurnaceTelemetry goes to the controller as it comes.
"""

from __future__ import annotations

import math

import can

from millctl.config.models import Bus, Interlock
from millctl.drives.base import DriveInfo
from millctl.protocol import (
    AliveCounter,
    BusReader,
    Codec,
    Command,
    Decoded,
    E2EReceiver,
    FaultFlag,
    FurnaceTelemetry,
    Heartbeat,
    MillMessage,
    NodeState,
    NodeStatus,
    ProtocolError,
    Setpoints,
    sequence_decay_s,
)

CHECKED: tuple[type[MillMessage], ...] = (NodeStatus, FurnaceTelemetry)
"""The furnace node's frames the link judges (its DriveTelemetry and PhysicsTelemetry it does not send)."""


class FurnaceLink:
    """The furnace node's bus: what the controller sends it, and what it last reported (times in s)."""

    def __init__(self, bus: can.BusABC, bus_config: Bus, codec: Codec, interlock: Interlock) -> None:
        self.bus = bus
        self.where = f"{bus_config.interface}:{bus_config.channel}"
        self.codec = codec
        self.reader = BusReader(bus, "controller (furnace bus)")
        self.counters: dict[type[MillMessage], AliveCounter] = {
            kind: AliveCounter() for kind in (Heartbeat, Setpoints, Command)
        }
        self.receivers = {
            kind: E2EReceiver(
                error_limit=interlock.e2e_error_limit,
                name=f"furnace node {kind.__name__}",
                sequence_decay_frames=interlock.e2e_sequence_decay_frames,
                min_decay_s=sequence_decay_s(interlock.e2e_sequence_decay_frames, codec.cycle_time_s(kind) or 1.0),
            )
            for kind in CHECKED
        }
        period_s = codec.cycle_time_s(NodeStatus) or 1.0
        self.stale_after_s = max(interlock.stale_periods * period_s, interlock.min_stale_s)
        """A NodeStatus older than this (s) means the furnace node is silent: the mill trips."""
        self.status: NodeStatus | None = None
        """The last fresh NodeStatus (None before the first, and after a RESET until the next)."""
        self.status_s = -math.inf
        self.challenge = 0
        """The challenge of the last fresh NodeStatus: the heartbeat to the furnace node echoes it."""
        self.temp_c: float | None = None

    @property
    def state(self) -> NodeState | None:
        """The furnace node's state in its last NodeStatus (None when not known)."""
        return None if self.status is None else self.status.state

    def send(self, message: MillMessage) -> None:
        """Encode one message with its kind's next alive counter and send it on the furnace's bus."""
        counter = self.counters[type(message)].next() if type(message) in self.counters else 0
        self.bus.send(self.codec.encode(message, counter))

    def drain(self, now_s: float) -> list[Decoded]:
        """Every frame waiting on the furnace's bus; the fresh FurnaceTelemetry for the controller."""
        out = []
        for frame in self.reader.drain().frames:
            try:
                decoded = self.codec.decode(frame)
            except ProtocolError as exc:
                self.reader.malformed(frame, exc)
                continue
            receiver = self.receivers.get(decoded.kind)
            if receiver is None or not receiver.check(decoded, now_s).fresh or decoded.message is None:
                continue
            message = decoded.message
            if isinstance(message, NodeStatus):
                self.status, self.status_s, self.challenge = message, now_s, message.challenge
            elif isinstance(message, FurnaceTelemetry):
                self.temp_c = message.temp_c
                out.append(decoded)
        return out

    def forget(self) -> None:
        """After a RESET: a status from before it does not count (the next one says whether it took)."""
        self.status = None
        for receiver in self.receivers.values():
            receiver.reset()

    def faults(self, now_s: float, *, estop_commanded: bool) -> list[tuple[FaultFlag, str]]:
        """What the furnace node's link and reports say went wrong: (flag, cause) to latch."""
        found = []
        for receiver in self.receivers.values():
            reason = receiver.fault_reason()
            if reason is not None:
                found.append((FaultFlag.E2E_LINK, f"furnace node on {self.where}: {reason}"))
        age_s = now_s - self.status_s
        if not math.isinf(self.status_s) and age_s > self.stale_after_s:
            found.append((FaultFlag.E2E_LINK, f"furnace node on {self.where} silent: NodeStatus age {age_s:.2f} s "
                          f"> bound {self.stale_after_s:.2f} s (interlock.stale_periods, min_stale_s)"))
        status = self.status
        if status is not None and status.state is NodeState.FAULT:
            bits = status.fault_bits & ~FaultFlag.ESTOP if estop_commanded else status.fault_bits
            if bits:
                lowest = FaultFlag(int(bits) & -int(bits))  # the report latches one fault code per cause
                found.append((lowest, f"furnace node on {self.where} in FAULT: first fault "
                              f"{status.first_fault.name}, fault bits {status.fault_bits!r}"))
        return found

    def estop_shown(self) -> bool:
        """The furnace node reports the E-stop latched."""
        return self.status is not None and FaultFlag.ESTOP in self.status.fault_bits

    def info(self, now_s: float) -> DriveInfo:
        """The furnace node for the operator: its state, its NodeStatus age and temperature."""
        parts = [f"millbus furnace node on {self.where}"]
        if not math.isinf(self.status_s):
            parts.append(f"NodeStatus {now_s - self.status_s:.2f} s ago")
        if self.temp_c is not None:
            parts.append(f"{self.temp_c:.1f} °C")
        state = self.state
        return DriveInfo("furnace", state.name if state is not None else "unknown", None, "; ".join(parts))


__all__ = ["CHECKED", "FurnaceLink"]

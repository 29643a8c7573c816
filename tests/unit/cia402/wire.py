"""A controller's side of the CiA 402 wire for the simulated drives' unit tests: raw frames, nothing threaded.

Expedited SDO (CiA 301), NMT, heartbeat and RPDO1 as the frames a controller
sends, so the tests step the simulated drives with a manual clock and read
every answer off the bus; :func:`cia402_config` turns the repository's config
into a CiA 402 mill (rotary node 2, vibration node 3, controller node 1).
"""

from __future__ import annotations

import struct
import uuid
from dataclasses import dataclass, field

import can

from firmware_sim.cia402 import Cia402Mill
from millctl.clock import ManualClock
from millctl.config import MillConfig
from millctl.config.loader import GENERIC_EDS, packaged_file

ROTARY_ID = 2
VIBRATION_ID = 3
CONTROLLER_ID = 1
UNITS_PER_RPM = 10.0
"""Drive units per motor rpm in the tests' config (0.1 rpm resolution)."""
GEAR_RATIO = 2.0
"""Motor rpm per mill rpm in the tests' config."""
_SIZE_COMMAND = {1: 0x2F, 2: 0x2B, 4: 0x23}


def cia402_config(config: MillConfig, *, mode: str = "profile-velocity") -> MillConfig:
    """``config`` with ``[drives] backend = "cia402"``: nodes 2 and 3, 10 units/rpm, gear 2, no furnace."""
    values = config.model_dump(mode="json")
    drives = values["drives"]
    drives.update(backend="cia402", controller_node_id=CONTROLLER_ID, furnace="none")
    for motor, node_id in (("rotary", ROTARY_ID), ("vibration", VIBRATION_ID)):
        drives[motor]["cia402"] = {
            "node_id": node_id,
            "eds": str(packaged_file(GENERIC_EDS)),
            "units_per_rpm": UNITS_PER_RPM,
            "gear_ratio": GEAR_RATIO,
            "mode": mode,
        }
    return MillConfig.model_validate(values)


def wire(mill_rpm: float) -> int:
    """A mill speed in drive velocity units (the tests' scaling)."""
    return round(mill_rpm * GEAR_RATIO * UNITS_PER_RPM)


class SdoAbort(Exception):
    """The drive aborted an SDO transfer (its abort code)."""

    def __init__(self, code: int) -> None:
        super().__init__(f"SDO abort 0x{code:08X}")
        self.code = code


@dataclass
class Wire:
    """The simulated drives and a controller's bus on one virtual channel, one manual clock."""

    config: MillConfig
    fault_injection: bool = True
    clock: ManualClock = field(default_factory=ManualClock)
    seen: list[can.Message] = field(default_factory=list)

    def __post_init__(self) -> None:
        channel = f"cia402-{uuid.uuid4().hex}"
        self.drive_bus = can.Bus(interface="virtual", channel=channel)
        self.bus = can.Bus(interface="virtual", channel=channel)
        self.mill = Cia402Mill(self.config, self.drive_bus, self.clock, fault_injection=self.fault_injection)
        self.dt_s = self.config.timing.node_tick_s

    def close(self) -> None:
        self.mill.close()
        self.drive_bus.shutdown()
        self.bus.shutdown()

    def step(self, heartbeat: bool = False) -> None:
        """One tick of the drives, then collect what they sent; advance the clock by a tick."""
        if heartbeat:
            self.send(0x700 + CONTROLLER_ID, [0x05])
        self.mill.tick()
        for msg in iter(lambda: self.bus.recv(timeout=0.0), None):
            self.seen.append(msg)
        self.clock.advance(self.dt_s)

    def run(self, seconds: float, *, heartbeat: bool = False, rpdo: dict[int, tuple[int, int]] | None = None) -> None:
        """Step for ``seconds``; each tick the heartbeat (if asked) and RPDO1 {node: (controlword, target)}."""
        for _ in range(round(seconds / self.dt_s)):
            for node_id, (controlword, target) in (rpdo or {}).items():
                self.rpdo(node_id, controlword, target)
            self.step(heartbeat=heartbeat)

    def send(self, cob_id: int, data: bytes | list[int]) -> None:
        self.bus.send(can.Message(arbitration_id=cob_id, data=bytes(data), is_extended_id=False))

    def nmt(self, command: int, node_id: int = 0) -> None:
        self.send(0x000, [command, node_id])
        self.step()

    def rpdo(self, node_id: int, controlword: int, target: int) -> None:
        self.send(0x200 + node_id, struct.pack("<Hi", controlword, target))

    def _sdo(self, node_id: int, request: bytes) -> bytes:
        start = len(self.seen)
        self.send(0x600 + node_id, request)
        self.step()
        for msg in self.seen[start:]:
            if msg.arbitration_id == 0x580 + node_id:
                if msg.data[0] == 0x80:
                    raise SdoAbort(struct.unpack_from("<I", msg.data, 4)[0])
                return bytes(msg.data)
        raise TimeoutError(f"no SDO answer from node {node_id}")

    def write(self, node_id: int, index: int, subindex: int, value: int, size: int, signed: bool = False) -> None:
        """Expedited SDO download of an integer of ``size`` bytes."""
        payload = value.to_bytes(size, "little", signed=signed).ljust(4, b"\x00")
        self._sdo(node_id, bytes([_SIZE_COMMAND[size]]) + struct.pack("<HB", index, subindex) + payload)

    def read(self, node_id: int, index: int, subindex: int = 0, signed: bool = False) -> int:
        """Expedited SDO upload of an integer."""
        answer = self._sdo(node_id, bytes([0x40]) + struct.pack("<HB", index, subindex) + bytes(4))
        size = 4 - ((answer[0] >> 2) & 0x3) if answer[0] & 0x1 else 4
        return int.from_bytes(answer[4:4 + size], "little", signed=signed)

    def frames(self, cob_id: int, after: int = 0) -> list[can.Message]:
        return [m for m in self.seen[after:] if m.arbitration_id == cob_id]

    def tpdo(self, node_id: int) -> tuple[int, int]:
        """The newest TPDO1 of a drive: (statusword, velocity actual in drive units)."""
        last = self.frames(0x180 + node_id)[-1]
        status, actual = struct.unpack_from("<Hi", last.data)
        return status, actual

"""``millctl bus check`` for CiA 402 drives: is each one there, is it the drive its EDS describes, what it holds.

It listens for each drive's heartbeat (its NMT state), reads the identity
object 0x1018 by SDO and compares it with the EDS's [DeviceInfo], checks that
the drive supports the configured mode (0x6502), and reads back the limits
millctl writes before arming (:func:`~millctl.drives.cia402.limits.drive_limits`)
and its heartbeat settings, saying in words what differs. It writes nothing:
the drives are left as they were (docs/deployment.md#standard-cia-402-drives).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Any

import can
import canopen
from canopen.sdo.exceptions import SdoError

from millctl.config.models import MillConfig
from millctl.drives.cia402.limits import LimitObject, drive_limits
from millctl.drives.cia402.report import NMT_NAMES
from millctl.drives.cia402.sdo_jobs import (
    MODE_OF_OPERATION,
    PRODUCER_HEARTBEAT_MS,
    SDO_TIMEOUT_S,
    read_identity,
    sdo_var,
)
from millctl.safety import Envelope

SUPPORTED_MODE_BIT = {3: 1 << 2, 2: 1 << 1}
"""0x6502 bit of each mode of operation (3 profile velocity: bit 2; 2 velocity: bit 1)."""


@dataclass
class DriveCheck:
    """What one drive answered, and what is wrong with it in words."""

    motor: str
    node_id: int
    nmt_state: str = "silent"
    identity: dict[str, int] = field(default_factory=dict)
    eds_match: bool = False
    limits: dict[str, dict[str, int | None]] = field(default_factory=dict)
    """Per object (``0x607F:00 max profile velocity``): what millctl writes before arming, what the drive holds."""
    problems: list[str] = field(default_factory=list)


@dataclass
class Cia402CheckReport:
    """Every drive's check."""

    drives: list[DriveCheck]

    @property
    def ok(self) -> bool:
        """True when no drive has a problem."""
        return not any(d.problems for d in self.drives)

    @property
    def problems(self) -> list[str]:
        """Every drive's problems, each naming its drive."""
        return [f"{d.motor} drive (node {d.node_id}): {p}" for d in self.drives for p in d.problems]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"drives": [asdict(d) for d in self.drives], "ok": self.ok}


def _read(node: canopen.RemoteNode, index: int, subindex: int) -> int:
    return int(sdo_var(node, index, subindex).raw)


def _check_one(motor: str, node: canopen.RemoteNode, heard: dict[int, int], want: list[LimitObject],
               mode: int, heartbeat_word: int) -> DriveCheck:
    node_id = int(node.id or 0)
    result = DriveCheck(motor, node_id)
    state = heard.get(node_id)
    if state is not None:
        result.nmt_state = NMT_NAMES.get(state, f"0x{state:02X}")
    try:
        identity = read_identity(node)
    except (SdoError, KeyError) as exc:
        heartbeat = "no heartbeat" if state is None else f"heartbeat {result.nmt_state}"
        result.problems.append(f"{heartbeat} at 0x{0x700 + node_id:03X} and no SDO answer for the identity 0x1018 "
                               f"({exc}): the drive is off, on another node ID or bitrate, or not on this bus")
        return result
    if state is None:  # it answers SDO: its producer heartbeat is off, and millctl sets it at start-up
        result.nmt_state = "no heartbeat (0x1017 = 0? millctl writes 100 ms at start-up)"
    result.identity = asdict(identity)
    info = node.object_dictionary.device_information
    eds_vendor, eds_product = info.vendor_number, info.product_number
    result.eds_match = (eds_vendor in (None, identity.vendor_id)) and (eds_product in (None, identity.product_code))
    if not result.eds_match:
        result.problems.append(
            f"the EDS describes vendor 0x{eds_vendor or 0:08X} product 0x{eds_product or 0:08X}, the drive says "
            f"vendor 0x{identity.vendor_id:08X} product 0x{identity.product_code:08X}: name this drive's own EDS "
            "in [drives.<motor>.cia402] eds"
        )
    checks = [*want, LimitObject(0x1017, 0, PRODUCER_HEARTBEAT_MS, "producer heartbeat time"),
              LimitObject(0x1016, 1, heartbeat_word, "consumer heartbeat time"),
              LimitObject(0x6007, 0, 3, "abort connection option code")]
    for limit in checks:
        try:
            held: int | None = _read(node, limit.index, limit.subindex)
        except (SdoError, KeyError) as exc:
            held = None
            result.problems.append(f"{limit.where} not readable ({exc})")
        result.limits[limit.where] = {"millctl_writes": limit.value, "drive_holds": held}
    try:
        supported = _read(node, 0x6502, 0)
        if not supported & SUPPORTED_MODE_BIT[mode]:
            result.problems.append(f"0x6502 supported drive modes 0x{supported:08X} lacks mode {mode} (0x6060) the "
                                   "config names: set [drives.<motor>.cia402] mode to one the drive supports")
    except (SdoError, KeyError) as exc:
        result.problems.append(f"0x6502 supported drive modes not readable ({exc})")
    return result


def check_drives(config: MillConfig, bus: can.BusABC, listen_s: float) -> Cia402CheckReport:
    """Listen for the drives' heartbeats for ``listen_s``, then read each one by SDO (writes nothing)."""
    network = canopen.Network(bus)
    heard: dict[int, int] = {}
    nodes: dict[str, canopen.RemoteNode] = {}
    for motor in ("rotary", "vibration"):
        cia = getattr(config.drives, motor).cia402
        node = network.add_node(cia.node_id, cia.eds)
        node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT_S
        nodes[motor] = node
        network.subscribe(0x700 + cia.node_id, lambda can_id, data, ts: heard.__setitem__(can_id - 0x700, data[0]))
    network.notifier = can.Notifier(bus, network.listeners, 0.05)
    try:
        deadline = time.monotonic() + listen_s
        while time.monotonic() < deadline and len(heard) < len(nodes):
            time.sleep(0.02)
        envelope = Envelope.from_config(config)
        consumer_ms = max(round(config.timing.watchdog_timeout_s * 1000), 1)
        word = (config.drives.controller_node_id << 16) | consumer_ms
        drives = []
        for motor, node in nodes.items():
            drive = getattr(config.drives, motor)
            want = drive_limits(motor, drive, drive.cia402, envelope, None)
            drives.append(_check_one(motor, node, heard, want, MODE_OF_OPERATION[drive.cia402.mode], word))
        return Cia402CheckReport(drives)
    finally:
        network.notifier.stop()


__all__ = ["Cia402CheckReport", "DriveCheck", "check_drives"]

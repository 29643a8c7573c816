"""The CiA 402 drives' SDO work, off the control loop's tick: start-up configuration and each move's limits.

python-canopen's SDO client blocks until the drive answers, so these run on
one worker thread while the tick goes on draining the bus (the answers reach
the client through ``Network.notify`` from the tick) and producing the
heartbeat. Each value written is read back; the first difference is the
job's refusal, naming the drive, the object, and both values.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import canopen
from canopen.sdo.base import SdoArray, SdoRecord, SdoVariable
from canopen.sdo.exceptions import SdoError

from millctl.config.models import Cia402Mode
from millctl.drives.cia402.limits import LimitObject, mismatch

log = logging.getLogger(__name__)

MODE_OF_OPERATION = {Cia402Mode.PROFILE_VELOCITY: 3, Cia402Mode.VELOCITY: 2}
"""0x6060 for each configured mode."""

TARGET_OBJECT = {Cia402Mode.PROFILE_VELOCITY: 0x60FF, Cia402Mode.VELOCITY: 0x6042}
ACTUAL_OBJECT = {Cia402Mode.PROFILE_VELOCITY: 0x606C, Cia402Mode.VELOCITY: 0x6044}

HEARTBEAT_LOSS_QUICK_STOP = 3
"""0x6007 abort connection option code 3: quick stop on loss of the controller's heartbeat."""

PRODUCER_HEARTBEAT_MS = 100
"""0x1017 millctl writes: each drive's own heartbeat, which the controller monitors (many drives ship with 0)."""

TPDO_EVENT_TIMER_MS = 50
"""TPDO1 event timer (ms): the millbus telemetry period."""

SDO_TIMEOUT_S = 1.0
"""How long one SDO answer may take (s; a loaded host delays the tick that delivers it)."""


@dataclass(frozen=True)
class Identity:
    """The drive's identity object 0x1018."""

    vendor_id: int
    product_code: int
    revision: int
    serial: int

    def __str__(self) -> str:
        return (f"vendor 0x{self.vendor_id:08X}, product 0x{self.product_code:08X}, "
                f"revision 0x{self.revision:08X}, serial {self.serial}")


def sdo_var(node: canopen.RemoteNode, index: int, subindex: int) -> SdoVariable:
    """The SDO variable at (index, subindex) of a drive."""
    entry = node.sdo[index]
    if isinstance(entry, (SdoRecord, SdoArray)):
        return entry[subindex]
    assert isinstance(entry, SdoVariable)
    return entry


def write_checked(motor: str, node: canopen.RemoteNode, limit: LimitObject) -> str:
    """Write one object and read it back: "" when it holds, else the refusal in words."""
    node_id = int(node.id or 0)
    try:
        var = sdo_var(node, limit.index, limit.subindex)
        var.raw = limit.value
        got = var.raw
    except (SdoError, KeyError) as exc:
        return f"{motor} drive (node {node_id}): {limit.where} write {limit.value} failed: {exc}"
    return "" if got == limit.value else mismatch(motor, node_id, limit, int(got))


def write_all(motor: str, node: canopen.RemoteNode, limits: list[LimitObject]) -> str:
    """Write and read back every object in order; the first refusal ends it."""
    for limit in limits:
        refusal = write_checked(motor, node, limit)
        if refusal:
            return refusal
    return ""


def read_identity(node: canopen.RemoteNode) -> Identity:
    """Read 0x1018 sub 1–4."""
    values = [int(node.sdo[0x1018][sub].raw) for sub in (1, 2, 3, 4)]
    return Identity(*values)


def map_pdos(motor: str, node: canopen.RemoteNode, mode: Cia402Mode) -> str:
    """RPDO1 = controlword + target, TPDO1 = statusword + actual (event timer 50 ms), saved and read back."""
    target, actual = TARGET_OBJECT[mode], ACTUAL_OBJECT[mode]
    node_id = int(node.id or 0)
    try:
        rpdo, tpdo = node.rpdo[1], node.tpdo[1]
        for pdo, objects, cob_id in ((rpdo, (0x6040, target), 0x200), (tpdo, (0x6041, actual), 0x180)):
            pdo.read()
            pdo.clear()
            for index in objects:
                pdo.add_variable(index)
            pdo.cob_id = cob_id + node_id
            pdo.trans_type = 255
            if pdo is tpdo:
                pdo.event_timer = TPDO_EVENT_TIMER_MS
            pdo.enabled = True
            pdo.save()
            pdo.read()
            mapped = [var.index for var in pdo.map]
            if mapped != list(objects) or not pdo.enabled or pdo.cob_id != cob_id + node_id:
                shown = ", ".join(f"0x{i:04X}" for i in mapped)
                wanted = ", ".join(f"0x{i:04X}" for i in objects)
                return (f"{motor} drive (node {node_id}): PDO mapping written [{wanted}] at 0x{cob_id + node_id:03X}, "
                        f"read back [{shown}] at 0x{pdo.cob_id or 0:03X}{'' if pdo.enabled else ' (disabled)'}")
    except (SdoError, KeyError, ValueError) as exc:
        return f"{motor} drive (node {node_id}): PDO mapping failed: {exc}"
    return ""


def _mode_shown(motor: str, node: canopen.RemoteNode, mode: Cia402Mode) -> str:
    """The mode written to 0x6060 is confirmed by 0x6061 (modes of operation display), not by 0x6060's read-back."""
    wanted = MODE_OF_OPERATION[mode]
    try:
        shown = int(sdo_var(node, 0x6061, 0).raw)
    except (SdoError, KeyError) as exc:
        return f"{motor} drive (node {node.id or 0}): 0x6061 modes of operation display not readable: {exc}"
    return "" if shown == wanted else (
        f"{motor} drive (node {node.id or 0}): 0x6060 modes of operation written {wanted}, 0x6061 display shows "
        f"{shown}: the drive did not take the mode (docs/deployment.md#standard-cia-402-drives)"
    )


def start_up(motor: str, node: canopen.RemoteNode, mode: Cia402Mode, controller_id: int,
             consumer_ms: int) -> tuple[str, Identity | None]:
    """Configure one drive in PRE-OPERATIONAL, then start it: (refusal or "", its identity)."""
    node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT_S
    node.nmt.send_command(0x80)  # enter PRE-OPERATIONAL: SDO yes, PDOs no
    try:
        identity = read_identity(node)
    except (SdoError, KeyError) as exc:
        return f"{motor} drive (node {node.id or 0}): identity 0x1018 not readable: {exc}", None
    settings = [
        LimitObject(0x1017, 0, PRODUCER_HEARTBEAT_MS, "producer heartbeat time"),
        LimitObject(0x1016, 1, (controller_id << 16) | consumer_ms, "consumer heartbeat time"),
        LimitObject(0x6007, 0, HEARTBEAT_LOSS_QUICK_STOP, "abort connection option code"),
        LimitObject(0x6060, 0, MODE_OF_OPERATION[mode], "modes of operation"),
    ]
    refusal = write_all(motor, node, settings) or _mode_shown(motor, node, mode) or map_pdos(motor, node, mode)
    if refusal:
        return refusal, identity
    node.nmt.send_command(0x01)  # start: OPERATIONAL, PDOs flow
    log.info("%s drive (node %d) configured and started: %s", motor, node.id, identity)
    return "", identity


__all__ = [
    "ACTUAL_OBJECT",
    "MODE_OF_OPERATION",
    "PRODUCER_HEARTBEAT_MS",
    "TARGET_OBJECT",
    "Identity",
    "map_pdos",
    "read_identity",
    "sdo_var",
    "start_up",
    "write_all",
    "write_checked",
]

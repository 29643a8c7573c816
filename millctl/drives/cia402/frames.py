"""CANopen frames in words, for ``millctl bus log show`` and ``bus monitor`` beside the millbus frames.

The predefined connection set (CiA 301 §7.3.5): the COB-ID's function code
(bits 7–10) and node ID (bits 0–6) name what a frame is — NMT (0x000), SYNC
(0x080), EMCY (0x080 + ID), PDOs (0x180 … 0x500 + ID), SDO (0x580/0x600 + ID),
heartbeat (0x700 + ID). PDO1 is read with the mapping millctl writes
(docs/protocol.md#cia-402): RPDO1 controlword + target velocity, TPDO1
statusword + velocity actual.
"""

from __future__ import annotations

import struct

import can

from millctl.drives.cia402.state402 import decode_statusword
from millctl.protocol import Codec, ProtocolError

NMT_COMMANDS = {0x01: "start (OPERATIONAL)", 0x02: "stop (STOPPED)", 0x80: "enter PRE-OPERATIONAL",
                0x81: "reset node", 0x82: "reset communication"}
HEARTBEAT_STATES = {0x00: "boot-up", 0x04: "STOPPED", 0x05: "OPERATIONAL", 0x7F: "PRE-OPERATIONAL"}
SDO_ABORTS = {0x05040000: "SDO protocol timed out", 0x06010000: "unsupported access", 0x06010002: "read-only",
              0x06020000: "object does not exist", 0x06090011: "sub-index does not exist",
              0x06090030: "value range exceeded", 0x08000000: "general error",
              0x08000022: "not possible in the present device state"}
_PDO = {0x180: ("TPDO", 1), 0x200: ("RPDO", 1), 0x280: ("TPDO", 2), 0x300: ("RPDO", 2),
        0x380: ("TPDO", 3), 0x400: ("RPDO", 3), 0x480: ("TPDO", 4), 0x500: ("RPDO", 4)}


def _power(statusword: int) -> str:
    return str(decode_statusword(statusword))


def _pdo1(kind: str, data: bytes) -> str:
    if len(data) >= 6:
        word, velocity = struct.unpack_from("<Hi", data)
    elif len(data) >= 4:
        word, velocity = struct.unpack_from("<Hh", data)
    else:
        return f"{data.hex()} (short)"
    if kind == "RPDO":
        return f"controlword 0x{word:04X}, target velocity {velocity}"
    return f"statusword 0x{word:04X} ({_power(word)}), velocity actual {velocity}"


def _sdo(direction: str, data: bytes) -> str:
    if len(data) < 4:
        return f"{data.hex()} (short)"
    command = data[0]
    index, subindex = struct.unpack_from("<HB", data, 1)
    where = f"0x{index:04X}:{subindex:02X}"
    ccs = command >> 5
    value = int.from_bytes(data[4:8 - ((command >> 2) & 0x3)] if command & 0x1 else data[4:8], "little")
    if ccs == 4:
        code = int.from_bytes(data[4:8], "little")
        return f"abort {where}: 0x{code:08X} {SDO_ABORTS.get(code, '')}".rstrip()
    if direction == "request":
        if ccs == 1:
            return f"write {where} = {value}" if command & 0x2 else f"write {where} (segmented)"
        if ccs == 2:
            return f"read {where}"
    else:
        if ccs == 3:
            return f"write {where} done"
        if ccs == 2:
            return f"read {where} = {value}" if command & 0x2 else f"read {where} (segmented)"
    return f"{where} command 0x{command:02X} {data[4:].hex()}"


def describe_canopen(frame: can.Message, controller_id: int = 1) -> str:
    """One CANopen frame in words (``"?"`` for an ID outside the predefined connection set)."""
    ident, data = frame.arbitration_id, bytes(frame.data)
    function, node = ident & 0x780, ident & 0x7F
    who = "controller" if node == controller_id else f"node {node}"
    if ident == 0x000:
        if len(data) < 2:
            return "NMT (short)"
        target = "all nodes" if data[1] == 0 else f"node {data[1]}"
        return f"NMT {NMT_COMMANDS.get(data[0], f'0x{data[0]:02X}')} → {target}"
    if ident == 0x080:
        return "SYNC"
    if function == 0x080:
        if len(data) < 3:
            return f"EMCY {who} (short)"
        code, register = struct.unpack_from("<HB", data)
        return f"EMCY {who}: error code 0x{code:04X}, error register 0x{register:02X}" + (
            " (error reset)" if code == 0 else "")
    if function in _PDO:
        kind, number = _PDO[function]
        body = _pdo1(kind, data) if number == 1 else data.hex()
        return f"{kind}{number} {'→' if kind == 'RPDO' else '←'} {who}: {body}"
    if function == 0x580:
        return f"SDO ← {who}: {_sdo('response', data)}"
    if function == 0x600:
        return f"SDO → {who}: {_sdo('request', data)}"
    if function == 0x700:
        state = HEARTBEAT_STATES.get(data[0] & 0x7F, f"0x{data[0]:02X}") if data else "(empty)"
        return f"heartbeat {who}: {state}"
    return "?"


def describe_frame(frame: can.Message, codec: Codec, *, canopen: bool, controller_id: int = 1) -> str:
    """A frame in words: CANopen first on a CiA 402 bus, the millbus DBC first otherwise; the other as fallback."""
    def millbus() -> str | None:
        try:
            decoded = codec.decode(frame)
        except ProtocolError:
            return None
        return f"{decoded.kind.__name__} {decoded.message}" if decoded.message is not None else (
            f"{decoded.kind.__name__} (CRC wrong)")

    if canopen:
        said = describe_canopen(frame, controller_id)
        return said if said != "?" else (millbus() or "?")
    return millbus() or describe_canopen(frame, controller_id)


__all__ = ["describe_canopen", "describe_frame"]

"""The typed codec: message dataclasses ↔ ``can.Message`` frames, through cantools and the DBC.

Nothing else in millctl packs bytes. ``Codec.encode`` checks every value
against its signal's range in the DBC (refusing, never clamping, with a
:class:`SignalRangeError` naming the signal, value and range) and fills the
alive counter and CRC of E2E-protected messages. ``Codec.decode`` turns any
frame into a :class:`Decoded` or raises :class:`ProtocolError`, never any
other exception: unknown or extended identifier, remote/error/FD frame, a
length other than 8, a value outside its DBC range or not in its value table
(unless the table is marked informational with the signal attribute
``ValueTableInformational``, as ``EStop.source``'s is: an E-stop is valid
whoever pressed it).

A frame whose CRC does not match decodes to ``Decoded(message=None,
crc_ok=False)``: its data are never handed out, but its receiver still
counts it (:class:`millctl.protocol.e2e.E2EReceiver`).
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import math
import typing
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import can
import cantools

from millctl.protocol.e2e import COUNTER_MODULO, e2e_crc
from millctl.protocol.errors import ProtocolError, SignalRangeError
from millctl.protocol.messages import MESSAGE_TYPES, MillMessage

DBC_NAME = "millbus.dbc"
CRC_SIGNAL = "crc"
COUNTER_SIGNAL = "counter"
FRAME_LENGTH = 8

M = TypeVar("M", bound=MillMessage)


@dataclass(frozen=True)
class Decoded:
    """One received frame, decoded.

    ``message`` is None exactly when ``crc_ok`` is False. ``counter`` is the
    alive counter of an E2E-protected message, None for the others (whose
    ``crc_ok`` is always True).
    """

    kind: type[MillMessage]
    message: MillMessage | None
    counter: int | None
    crc_ok: bool
    frame_id: int
    timestamp: float = 0.0


@dataclass(frozen=True)
class _Field:
    name: str
    convert: Callable[[Any], Any]
    minimum: float
    maximum: float
    unit: str
    choices: frozenset[int] | None
    integer: bool
    tolerance: float  # how far a decoded value may stray from the range by rounding: 1e-9 of its magnitude


@dataclass(frozen=True)
class _Spec:
    kind: type[MillMessage]
    dbc: Any
    data_id: int | None
    fields: tuple[_Field, ...]


def _converter(hint: Any) -> tuple[Callable[[Any], Any], bool]:
    """How to turn a decoded number into the field's type, and whether the field is an integer."""
    if isinstance(hint, type) and issubclass(hint, enum.Enum):
        return (lambda raw: hint(int(raw))), True
    if hint is bool:
        return (lambda raw: bool(int(raw))), True
    if hint is int:
        return int, True
    if hint is float:
        return float, False
    raise ProtocolError(f"message field type {hint!r} has no wire form")


class Codec:
    """Encode and decode the mill bus messages with the DBC (the packaged ``millbus.dbc`` by default)."""

    def __init__(self, dbc_path: str | Path | None = None) -> None:
        path = Path(dbc_path) if dbc_path is not None else _packaged_dbc()
        try:
            database = cantools.database.load_file(str(path), strict=True)
        except Exception as exc:
            raise ProtocolError(f"cannot load the bus database {path}: {exc}") from exc
        if not isinstance(database, cantools.database.can.Database):
            raise ProtocolError(f"{path} is not a CAN database")
        self.database = database
        self.path = path
        self._by_kind: dict[type[MillMessage], _Spec] = {}
        self._by_id: dict[int, _Spec] = {}
        for kind in MESSAGE_TYPES:
            spec = self._spec(kind)
            self._by_kind[kind] = spec
            self._by_id[spec.dbc.frame_id] = spec

    def _spec(self, kind: type[MillMessage]) -> _Spec:
        try:
            dbc = self.database.get_message_by_name(kind.__name__)
        except KeyError:
            raise ProtocolError(f"{self.path} has no message {kind.__name__}") from None
        if dbc.is_extended_frame or dbc.length != FRAME_LENGTH:
            raise ProtocolError(f"{self.path}: {kind.__name__} must be an 11-bit, 8-byte frame")
        hints = typing.get_type_hints(kind)
        fields = []
        for item in dataclasses.fields(kind):
            signal = dbc.get_signal_by_name(item.name)
            convert, integer = _converter(hints[item.name])
            choices = None if _informational(signal) else frozenset(int(key) for key in signal.choices or ()) or None
            if signal.minimum is None or signal.maximum is None:
                raise ProtocolError(f"{self.path}: {kind.__name__}.{item.name} has no range")
            low, high = float(signal.minimum), float(signal.maximum)
            tolerance = 1e-9 * max(1.0, abs(high), abs(low))
            fields.append(_Field(item.name, convert, low, high, signal.unit or "", choices, integer, tolerance))
        attribute = dbc.dbc.attributes.get("E2EDataID") if dbc.dbc else None
        data_id = int(attribute.value) if attribute is not None and attribute.value else None
        signals = {signal.name for signal in dbc.signals}
        if (data_id is not None) != kind.E2E or (kind.E2E and not {CRC_SIGNAL, COUNTER_SIGNAL} <= signals):
            raise ProtocolError(f"{self.path}: {kind.__name__} E2E protection disagrees with the message class")
        carried = {item.name for item in fields} | ({CRC_SIGNAL, COUNTER_SIGNAL} if kind.E2E else set())
        if signals != carried:
            raise ProtocolError(
                f"{self.path}: {kind.__name__} has signals {sorted(signals - carried)} that the message class "
                "does not carry (millctl/protocol/messages.py)"
            )
        if kind.E2E and not _is_byte_0(dbc.get_signal_by_name(CRC_SIGNAL)):
            raise ProtocolError(
                f"{self.path}: {kind.__name__}.crc must be byte 0 (start bit 0, 8 bits, Intel, unsigned: "
                "0|8@1+; docs/protocol.md)"
            )
        return _Spec(kind, dbc, data_id, tuple(fields))

    def frame_id(self, kind: type[MillMessage]) -> int:
        """The 11-bit identifier of a message class."""
        return int(self._by_kind[kind].dbc.frame_id)

    def cycle_time_s(self, kind: type[MillMessage]) -> float | None:
        """The DBC cycle time (s) of a periodic message, None for event messages."""
        cycle_ms = self._by_kind[kind].dbc.cycle_time
        return cycle_ms / 1000.0 if cycle_ms else None

    def data_id(self, kind: type[MillMessage]) -> int | None:
        """The E2E data ID of a protected message, None for unprotected ones."""
        return self._by_kind[kind].data_id

    def signal_range(self, kind: type[MillMessage], field: str) -> tuple[float, float]:
        """The (minimum, maximum) the DBC allows for a field, in its unit."""
        for item in self._by_kind[kind].fields:
            if item.name == field:
                return item.minimum, item.maximum
        raise KeyError(f"{kind.__name__} has no field {field!r}")

    def saturated(self, message: M) -> M:
        """A copy with every real-valued field clamped into its DBC range (for measurements, never setpoints)."""
        changes: dict[str, float] = {}
        for item in self._spec_of(message).fields:
            value = getattr(message, item.name)
            if not item.integer and math.isfinite(value):
                changes[item.name] = min(max(float(value), item.minimum), item.maximum)
        return typing.cast(M, dataclasses.replace(typing.cast(Any, message), **changes))

    def _spec_of(self, message: MillMessage) -> _Spec:
        spec = self._by_kind.get(type(message))
        if spec is None:
            raise TypeError(f"{type(message).__name__} is not a mill bus message")
        return spec

    def encode(self, message: MillMessage, counter: int = 0) -> can.Message:
        """The frame for a message; E2E messages carry ``counter`` (0…15) and their CRC."""
        # cantools encodes with strict=False: what its strict mode asserts is checked already, and more
        # narrowly: the DBC message has exactly the class's signals (checked at load), each value is in its
        # range (cantools allows 1e-6 of a step beyond it) and its value table (_checked), the counter is
        # 0…15. Its strict check cost as much again as the encoding, on every frame of every 100 Hz loop.
        spec = self._spec_of(message)
        data: dict[str, int | float] = {}
        for item in spec.fields:
            data[item.name] = _checked(spec, item, getattr(message, item.name))
        if spec.data_id is not None:
            if isinstance(counter, bool) or not isinstance(counter, int) or not 0 <= counter < COUNTER_MODULO:
                raise SignalRangeError(spec.dbc.name, COUNTER_SIGNAL, counter, 0, COUNTER_MODULO - 1, "")
            data[COUNTER_SIGNAL] = counter
            data[CRC_SIGNAL] = 0
            payload = spec.dbc.encode(data, strict=False)
            # the CRC is byte 0 (checked when the DBC was loaded) over bytes 1-7: set it in place, no second
            # encode (a cantools encode is most of this method's time, on every frame of every 100 Hz loop)
            payload = bytes((e2e_crc(spec.data_id, payload[1:]),)) + payload[1:]
        else:
            payload = spec.dbc.encode(data, strict=False)
        return can.Message(arbitration_id=spec.dbc.frame_id, data=payload, is_extended_id=False, dlc=FRAME_LENGTH)

    def decode(self, frame: can.Message) -> Decoded:
        """Decode a received frame; anything that does not fit the DBC raises :class:`ProtocolError`."""
        try:
            return self._decode(frame)
        except ProtocolError:
            raise
        except Exception as exc:
            raise ProtocolError(f"undecodable frame {frame!r}: {type(exc).__name__}: {exc}") from exc

    def _decode(self, frame: can.Message) -> Decoded:
        frame_id = int(frame.arbitration_id)
        if frame.is_extended_id or frame.is_remote_frame or frame.is_error_frame or frame.is_fd:
            raise ProtocolError(f"frame 0x{frame_id:X}: extended, remote, error or FD frames are not on this bus")
        spec = self._by_id.get(frame_id)
        if spec is None:
            raise ProtocolError(f"frame 0x{frame_id:03X}: unknown identifier (not in {self.path.name})")
        data = bytes(frame.data)
        if len(data) != FRAME_LENGTH or frame.dlc != FRAME_LENGTH:
            raise ProtocolError(
                f"frame 0x{frame_id:03X} ({spec.dbc.name}): length {len(data)}, expected {FRAME_LENGTH} bytes"
            )
        raw = spec.dbc.decode(data, decode_choices=False, scaling=True)
        timestamp = float(frame.timestamp or 0.0)
        counter: int | None = None
        if spec.data_id is not None:
            counter = int(raw[COUNTER_SIGNAL])
            if e2e_crc(spec.data_id, data[1:]) != data[0]:
                return Decoded(spec.kind, None, counter, False, frame_id, timestamp)
        values = {}
        for item in spec.fields:
            value = raw[item.name]
            if not item.minimum - item.tolerance <= value <= item.maximum + item.tolerance or (
                item.choices is not None and int(value) not in item.choices
            ):
                raise ProtocolError(
                    f"frame 0x{frame_id:03X} ({spec.dbc.name}): {item.name} = {value!r} is outside "
                    f"{item.minimum:g} … {item.maximum:g} or its value table"
                )
            try:
                values[item.name] = item.convert(value)
            except ValueError as exc:
                raise ProtocolError(f"frame 0x{frame_id:03X} ({spec.dbc.name}): {item.name}: {exc}") from exc
        return Decoded(spec.kind, spec.kind(**values), counter, True, frame_id, timestamp)


INFORMATIONAL_TABLE = "ValueTableInformational"
"""Signal attribute: 1 when the signal's value table only names values (EStop.source), 0 (default) when it
is the set of valid values, checked on encode and decode."""


def _informational(signal: Any) -> bool:
    """True when the signal's value table is informational: any value in its range is valid."""
    attribute = signal.dbc.attributes.get(INFORMATIONAL_TABLE) if signal.dbc else None
    return attribute is not None and bool(attribute.value)


def _is_byte_0(signal: Any) -> bool:
    """True when a signal is exactly byte 0 of the frame: start bit 0, 8 bits, little-endian, unsigned."""
    return bool(
        signal.start == 0 and signal.length == 8 and signal.byte_order == "little_endian" and not signal.is_signed
    )


def _checked(spec: _Spec, item: _Field, value: Any) -> int | float:
    """The wire value of one field, refusing what the signal cannot carry."""

    def refuse() -> SignalRangeError:
        return SignalRangeError(spec.dbc.name, item.name, value, item.minimum, item.maximum, item.unit)

    if isinstance(value, int):  # also bool, IntEnum and IntFlag
        number: int | float = int(value)
    elif isinstance(value, float):
        number = value
    else:
        raise refuse()
    if not math.isfinite(number) or not item.minimum <= number <= item.maximum:
        raise refuse()
    if item.integer and number != int(number):
        raise refuse()
    if item.choices is not None and int(number) not in item.choices:
        raise refuse()
    return number


def _packaged_dbc() -> Path:
    from millctl.config.loader import packaged_file

    return packaged_file(DBC_NAME)


@functools.cache
def default_codec() -> Codec:
    """The codec of the packaged ``millbus.dbc``, loaded once per process."""
    return Codec()


__all__ = ["DBC_NAME", "INFORMATIONAL_TABLE", "Codec", "Decoded", "default_codec"]

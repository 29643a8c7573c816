"""The typed codec: round trips at range edges, refusals, E2E fields and a decoder fuzz."""

from __future__ import annotations

import dataclasses
import enum
import math
import typing
from typing import Any

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from millctl.errors import BusError, InvalidInputError
from millctl.protocol import (
    ESTOP_ID,
    MESSAGE_TYPES,
    Codec,
    Command,
    CommandCode,
    ControllerState,
    Decoded,
    EStop,
    EStopSource,
    FaultCode,
    FaultFlag,
    Heartbeat,
    MillMessage,
    NodeStatus,
    ProtocolError,
    Setpoints,
    SignalRangeError,
    default_codec,
    e2e_crc,
)
from millctl.protocol.codec import INFORMATIONAL_TABLE

CODEC = default_codec()


def edge_message(kind: type[MillMessage], high: bool) -> MillMessage:
    """A message with every field at its lowest (or highest) DBC value."""
    hints = typing.get_type_hints(kind)
    values: dict[str, Any] = {}
    for field in dataclasses.fields(kind):
        hint = hints[field.name]
        low, top = CODEC.signal_range(kind, field.name)
        if isinstance(hint, type) and issubclass(hint, enum.IntFlag):
            values[field.name] = hint(int(top if high else low))
        elif isinstance(hint, type) and issubclass(hint, enum.Enum):
            members = list(hint)
            values[field.name] = members[-1] if high else members[0]
        elif hint is bool:
            values[field.name] = high
        elif hint is int:
            values[field.name] = int(top if high else low)
        else:
            values[field.name] = top if high else low
    return kind(**values)


def assert_same(original: MillMessage, decoded: MillMessage | None) -> None:
    assert decoded is not None
    assert type(decoded) is type(original)
    for field in dataclasses.fields(original):
        want, got = getattr(original, field.name), getattr(decoded, field.name)
        if isinstance(want, float) and not isinstance(want, bool):
            assert got == pytest.approx(want, abs=1e-6), field.name
        else:
            assert got == want, field.name
            assert type(got) is type(want), field.name


@pytest.mark.parametrize("kind", MESSAGE_TYPES, ids=lambda k: k.__name__)
@pytest.mark.parametrize("high", [False, True], ids=["min", "max"])
def test_every_message_round_trips_at_its_range_edges(kind: type[MillMessage], high: bool) -> None:
    message = edge_message(kind, high)
    counter = 15 if high else 0
    frame = CODEC.encode(message, counter=counter)
    assert frame.arbitration_id == CODEC.frame_id(kind)
    assert not frame.is_extended_id and frame.dlc == 8 and len(frame.data) == 8
    decoded = CODEC.decode(frame)
    assert decoded.crc_ok and decoded.kind is kind
    assert decoded.counter == (counter if kind.E2E else None)
    assert_same(message, decoded.message)


def numeric_fields() -> list[tuple[type[MillMessage], str, str]]:
    out = []
    for kind in MESSAGE_TYPES:
        hints = typing.get_type_hints(kind)
        for f in dataclasses.fields(kind):
            if hints[f.name] in (float, int):
                sides = ["below", "above"] + (["nan"] if hints[f.name] is float else [])
                out += [(kind, f.name, side) for side in sides]
    return out


@pytest.mark.parametrize(("kind", "name", "side"), numeric_fields(), ids=lambda x: getattr(x, "__name__", x))
def test_out_of_range_encode_is_refused_with_name_value_and_range(
    kind: type[MillMessage], name: str, side: str
) -> None:
    low, top = CODEC.signal_range(kind, name)
    base = edge_message(kind, high=False)
    is_int = typing.get_type_hints(kind)[name] is int
    if side == "nan":
        bad: float = math.nan
    else:
        step = 1 if is_int else 0.5
        bad = low - step if side == "below" else top + step
    changes: dict[str, Any] = {name: bad}
    message = dataclasses.replace(base, **changes)
    with pytest.raises(SignalRangeError) as caught:
        CODEC.encode(message)
    text = str(caught.value)
    assert f"{kind.__name__}.{name}" in text
    assert repr(bad) in text
    assert f"{low:g}" in text and f"{top:g}" in text
    assert isinstance(caught.value, InvalidInputError)


def test_setpoint_range_covers_the_mill() -> None:
    assert CODEC.signal_range(Setpoints, "rotary_rpm")[1] >= 1000
    assert CODEC.signal_range(Setpoints, "vibration_rpm")[1] >= 2000
    assert CODEC.signal_range(Setpoints, "furnace_c") == (-50, 1700)


def test_values_outside_the_value_table_and_bad_counters_are_refused() -> None:
    with pytest.raises(SignalRangeError, match=r"Command\.command = 0"):
        CODEC.encode(Command(command=0))  # type: ignore[arg-type]
    with pytest.raises(SignalRangeError, match=r"Heartbeat\.counter = 16"):
        CODEC.encode(Heartbeat(ControllerState.IDLE), counter=16)
    status = edge_message(NodeStatus, False)
    assert isinstance(status, NodeStatus)
    with pytest.raises(SignalRangeError, match="refused_setpoints"):
        CODEC.encode(dataclasses.replace(status, refused_setpoints=1.5))  # type: ignore[arg-type]  # a count, not 1.5


def test_estop_has_the_highest_priority_identifier() -> None:
    assert CODEC.frame_id(EStop) == ESTOP_ID == 0
    others = [CODEC.frame_id(kind) for kind in MESSAGE_TYPES if kind is not EStop]
    assert min(others) > ESTOP_ID
    assert len(set(others)) == len(others)


def test_estop_source_has_a_value_table_and_it_is_informational() -> None:
    """The DBC names the sources (EStopSource); an E-stop from a source it does not name is still an E-stop."""
    signal = CODEC.database.get_message_by_name("EStop").get_signal_by_name("source")
    assert signal.choices is not None and signal.dbc is not None
    assert {int(k): str(v) for k, v in signal.choices.items()} == {s.value: s.name for s in EStopSource}
    assert signal.dbc.attributes[INFORMATIONAL_TABLE].value == 1
    for source in (*EStopSource, 7, 255):
        decoded = CODEC.decode(CODEC.encode(EStop(source)))
        assert decoded.message == EStop(int(source))
    foreign = can.Message(arbitration_id=ESTOP_ID, data=bytes([200, 0, 0, 0, 0, 0, 0, 0]), is_extended_id=False)
    assert CODEC.decode(foreign).message == EStop(200)  # a button wired by someone else: decoded as sent
    with pytest.raises(SignalRangeError, match=r"EStop\.source = 256"):
        CODEC.encode(EStop(256))  # the range still holds


def test_every_periodic_message_has_a_cycle_time_and_heartbeat_is_20_hz() -> None:
    assert CODEC.cycle_time_s(Heartbeat) == pytest.approx(0.05)
    for kind in MESSAGE_TYPES:
        send_type = CODEC.database.get_message_by_name(kind.__name__).send_type
        assert (send_type == "Cyclic") == (CODEC.cycle_time_s(kind) is not None), kind.__name__


def test_fault_codes_match_fault_flags() -> None:
    for flag in FaultFlag:
        assert FaultCode.of(flag).flag == flag
        assert FaultCode.of(flag).name == flag.name
    assert FaultCode.of(FaultFlag(0)) is FaultCode.NONE
    with pytest.raises(ValueError):
        FaultCode.of(FaultFlag.WATCHDOG | FaultFlag.STALL)


def corrupt(frame: can.Message, byte: int, mask: int) -> can.Message:
    data = bytearray(frame.data)
    data[byte] ^= mask
    return can.Message(arbitration_id=frame.arbitration_id, data=bytes(data), is_extended_id=False)


def test_a_flipped_bit_anywhere_fails_the_crc_and_hides_the_data() -> None:
    frame = CODEC.encode(Setpoints(100.0, 600.0, 300.0, True), counter=3)
    for byte in range(8):
        for bit in range(8):
            decoded = CODEC.decode(corrupt(frame, byte, 1 << bit))
            assert not decoded.crc_ok and decoded.message is None
            assert decoded.kind is Setpoints


def test_a_frame_replayed_under_another_identifier_fails_its_crc() -> None:
    frame = CODEC.encode(Command(CommandCode.ARM), counter=1)
    moved = can.Message(arbitration_id=CODEC.frame_id(Heartbeat), data=frame.data, is_extended_id=False)
    decoded = CODEC.decode(moved)
    assert decoded.kind is Heartbeat and not decoded.crc_ok


@pytest.mark.parametrize(
    "frame",
    [
        can.Message(arbitration_id=0x7FF, data=bytes(8), is_extended_id=False),
        can.Message(arbitration_id=0x020, data=bytes(7), is_extended_id=False),
        can.Message(arbitration_id=0x020, data=bytes(8), is_extended_id=True),
        can.Message(arbitration_id=0x020, is_remote_frame=True, dlc=8, is_extended_id=False),
        can.Message(arbitration_id=0x020, data=bytes(8), is_fd=True, is_extended_id=False),
        can.Message(arbitration_id=0x000, data=bytes(2), is_extended_id=False),
    ],
    ids=["unknown-id", "short", "extended", "remote", "fd", "short-estop"],
)
def test_frames_that_do_not_fit_the_dbc_raise_protocol_error(frame: can.Message) -> None:
    with pytest.raises(ProtocolError):
        CODEC.decode(frame)


def test_protocol_error_is_a_bus_error() -> None:
    assert issubclass(ProtocolError, BusError)


def test_codec_loads_an_explicit_dbc_path_and_reports_a_missing_one(tmp_path: Any) -> None:
    assert Codec(CODEC.path).frame_id(Heartbeat) == CODEC.frame_id(Heartbeat)
    with pytest.raises(ProtocolError, match="cannot load"):
        Codec(tmp_path / "missing.dbc")


@pytest.mark.parametrize(
    "crc", ["SG_ crc : 0|4@1+ (1,0) [0|15]", "SG_ crc : 7|8@0+ (1,0) [0|255]", "SG_ crc : 0|8@1- (1,0) [-128|127]"]
)
def test_a_dbc_whose_crc_is_not_byte_0_is_refused_when_loaded(tmp_path: Any, crc: str) -> None:
    """The encoder writes the CRC into byte 0 of the frame: a DBC that puts it elsewhere is refused, by name."""
    text = CODEC.path.read_text(encoding="utf-8")
    dbc = tmp_path / "moved-crc.dbc"
    dbc.write_text(text.replace("SG_ crc : 0|8@1+ (1,0) [0|255]", crc, 1), encoding="utf-8")
    with pytest.raises(ProtocolError, match=r"Command\.crc must be byte 0"):
        Codec(dbc)


def test_a_dbc_message_with_a_signal_its_class_does_not_carry_is_refused_when_loaded(tmp_path: Any) -> None:
    """The encoder fills exactly the class's fields (cantools' own strict check is not run per frame)."""
    text = CODEC.path.read_text(encoding="utf-8")
    command = 'SG_ command : 16|8@1+ (1,0) [1|4] "" Node'
    assert command in text
    dbc = tmp_path / "extra-signal.dbc"
    dbc.write_text(text.replace(command, command + '\n SG_ spare : 24|8@1+ (1,0) [0|255] "" Node', 1), "utf-8")
    with pytest.raises(ProtocolError, match=r"Command has signals \['spare'\] that the message class does not"):
        Codec(dbc)


def test_the_crc_is_byte_0_over_bytes_1_to_7_of_what_the_dbc_packs() -> None:
    """Byte 0 of every E2E frame is the CRC of its data ID and bytes 1-7, the rest is the DBC's packing."""
    messages: list[MillMessage] = [
        Command(CommandCode.ARM),
        Heartbeat(ControllerState.RUNNING, 0xBEEF),
        Setpoints(100.0, 600.0, 300.0, True),
    ]
    for message in messages:
        kind = type(message)
        frame = CODEC.encode(message, counter=7)
        data_id = CODEC.data_id(kind)
        assert data_id is not None
        values = {f.name: getattr(message, f.name) for f in dataclasses.fields(message)}
        packed = CODEC.database.get_message_by_name(kind.__name__).encode(
            {**values, "counter": 7, "crc": frame.data[0]}, strict=True
        )
        assert bytes(frame.data) == packed
        assert frame.data[0] == e2e_crc(data_id, bytes(frame.data[1:]))


FRAME_IDS = [CODEC.frame_id(kind) for kind in MESSAGE_TYPES]


@settings(max_examples=400, deadline=None)
@given(frame_id=st.sampled_from(FRAME_IDS), data=st.binary(min_size=8, max_size=8))
def test_fuzz_random_payloads_never_escape_the_decoder_nor_pass_a_wrong_crc(frame_id: int, data: bytes) -> None:
    frame = can.Message(arbitration_id=frame_id, data=data, is_extended_id=False)
    try:
        decoded: Decoded = CODEC.decode(frame)
    except ProtocolError:
        return
    data_id = CODEC.data_id(decoded.kind)
    if data_id is not None and e2e_crc(data_id, data[1:]) != data[0]:
        assert not decoded.crc_ok and decoded.message is None
    if decoded.crc_ok:
        assert decoded.message is not None
        # Whatever was accepted re-encodes to the very same bytes.
        assert bytes(CODEC.encode(decoded.message, counter=decoded.counter or 0).data) == data or not _canonical(
            decoded, data
        )


def _canonical(decoded: Decoded, data: bytes) -> bool:
    """True when the payload has no bits outside its signals (only then must re-encoding reproduce it)."""
    message = CODEC.database.get_message_by_frame_id(decoded.frame_id)
    used = 0
    for signal in message.signals:
        used |= ((1 << signal.length) - 1) << signal.start
    return int.from_bytes(data, "little") & ~used == 0


@settings(max_examples=200, deadline=None)
@given(
    frame_id=st.sampled_from(FRAME_IDS),
    counter=st.integers(0, 15),
    data=st.binary(min_size=7, max_size=7),
)
def test_fuzz_frames_with_a_correct_crc_are_accepted_or_refused_never_crash(
    frame_id: int, counter: int, data: bytes
) -> None:
    kind = next(k for k in MESSAGE_TYPES if CODEC.frame_id(k) == frame_id)
    data_id = CODEC.data_id(kind)
    if data_id is None:
        return
    body = bytes((data[0] & 0xF0 | counter,)) + data[1:]
    frame = can.Message(arbitration_id=frame_id, data=bytes((e2e_crc(data_id, body),)) + body, is_extended_id=False)
    try:
        decoded = CODEC.decode(frame)
    except ProtocolError:
        return
    assert decoded.crc_ok and decoded.counter == counter and isinstance(decoded.message, kind)

"""CANopen frames in words (``bus log show``, ``bus monitor``), beside the millbus ones."""

from __future__ import annotations

import json

import can
import pytest

from millctl.cli import main
from millctl.drives.cia402.frames import describe_canopen, describe_frame
from millctl.errors import ExitCode
from millctl.protocol import CommandCode, default_codec
from millctl.protocol.messages import Command


def _frame(ident: int, data: str) -> can.Message:
    return can.Message(arbitration_id=ident, data=bytes.fromhex(data), is_extended_id=False)


@pytest.mark.parametrize(
    ("ident", "data", "words"),
    [
        (0x000, "0102", "NMT start (OPERATIONAL) → node 2"),
        (0x000, "8100", "NMT reset node → all nodes"),
        (0x701, "05", "heartbeat controller: OPERATIONAL"),
        (0x703, "00", "heartbeat node 3: boot-up"),
        (0x702, "7f", "heartbeat node 2: PRE-OPERATIONAL"),
        (0x082, "1081110000000000", "EMCY node 2: error code 0x8110, error register 0x11"),
        (0x083, "0000000000000000", "EMCY node 3: error code 0x0000, error register 0x00 (error reset)"),
        (0x202, "0f00e8030000", "RPDO1 → node 2: controlword 0x000F, target velocity 1000"),
        (0x183, "3702fcffffff", "TPDO1 ← node 3: statusword 0x0237 (OPERATION ENABLED), velocity actual -4"),
        (0x182, "1802", "TPDO1 ← node 2: 1802 (short)"),
        (0x602, "2b7f60002c010000", "SDO → node 2: write 0x607F:00 = 300"),
        (0x582, "607f600000000000", "SDO ← node 2: write 0x607F:00 done"),
        (0x602, "4018100100000000", "SDO → node 2: read 0x1018:01"),
        (0x582, "4b7f60002d010000", "SDO ← node 2: read 0x607F:00 = 301"),
        (0x582, "807f600000000206", "SDO ← node 2: abort 0x607F:00: 0x06020000 object does not exist"),
        (0x080, "", "SYNC"),
    ],
)
def test_each_canopen_frame_says_what_it_is(ident: int, data: str, words: str) -> None:
    assert describe_canopen(_frame(ident, data)) == words


def test_on_a_cia402_bus_canopen_comes_first_and_millbus_frames_are_still_read() -> None:
    codec = default_codec()
    command = codec.encode(Command(CommandCode.ARM), 1)  # 0x010: a millbus frame, no CANopen function at node 16
    assert describe_frame(_frame(0x000, "0100"), codec, canopen=True).startswith("NMT start")
    assert describe_frame(command, codec, canopen=False).startswith("Command")


def test_an_id_outside_the_predefined_set_is_a_question_mark() -> None:
    assert describe_canopen(_frame(0x7E5, "00")) == "?"


def test_bus_monitor_json_without_an_end_is_refused_before_the_bus_opens(capsys: pytest.CaptureFixture[str]) -> None:
    """Its one document lists every frame heard: with no --duration-s a babbling bus would grow it without bound."""
    assert main(["bus", "monitor", "--json"]) == ExitCode.INVALID_INPUT
    document = json.loads(capsys.readouterr().out)
    assert document["ok"] is False and "--duration-s" in document["error"]["message"]

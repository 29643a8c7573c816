"""``millctl bus log convert``: a candump session log to ASC, BLF and TRC, frames, direction and channel intact."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import can
import pytest

from millctl.cli import main
from millctl.errors import ExitCode
from millctl.protocol import ControllerState, FaultCode, FaultFlag, Heartbeat, NodeState, NodeStatus, default_codec
from millctl.protocol.buslog import RotatingBusLog

CODEC = default_codec()


def _session(path: Path) -> list[can.Message]:
    """A little session as the service logs it: Heartbeats sent (Tx), NodeStatus received (Rx), one channel."""
    frames = []
    for i in range(5):
        sent = CODEC.encode(Heartbeat(ControllerState.IDLE), counter=i)
        sent.is_rx = False
        received = CODEC.encode(NodeStatus(NodeState.DISABLED, FaultFlag(0), FaultCode.NONE), counter=i)
        for offset, frame in enumerate((sent, received)):
            frame.timestamp = 1000.0 + 0.1 * i + 0.01 * offset
            frame.channel = "can0"
            frames.append(frame)
    log = RotatingBusLog(path, rotate_bytes=1 << 20, keep_files=1)
    for frame in frames:
        log.on_message_received(frame)
    log.stop()
    return frames


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".trc"])
def test_a_session_log_converts_with_direction_and_frames_intact(tmp_path: Path, suffix: str) -> None:
    source = tmp_path / "bus_session.log"
    frames = _session(source)
    target = tmp_path / f"bus_session{suffix}"
    assert main(["bus", "log", "convert", str(source), str(target)]) == ExitCode.OK
    back = list(can.LogReader(target))
    assert [(m.arbitration_id, bytes(m.data)) for m in back] == [(m.arbitration_id, bytes(m.data)) for m in frames]
    assert [m.is_rx for m in back] == [m.is_rx for m in frames]


def test_convert_refuses_an_unknown_format_a_missing_log_and_an_existing_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = tmp_path / "bus.log"
    _session(source)
    assert main(["bus", "log", "convert", str(source), str(tmp_path / "out.xyz")]) == ExitCode.INVALID_INPUT
    assert ".xyz is not one of" in capsys.readouterr().err
    assert main(["bus", "log", "convert", str(tmp_path / "none.log"), str(tmp_path / "o.asc")]) == 1
    assert "no such file" in capsys.readouterr().err
    assert main(["bus", "log", "convert", str(source), str(source)]) == ExitCode.INVALID_INPUT
    assert "refusing to overwrite" in capsys.readouterr().err
    if importlib.util.find_spec("asammdf") is None:
        assert main(["bus", "log", "convert", str(source), str(tmp_path / "o.mf4")]) == ExitCode.INVALID_INPUT
        assert "millctl[mf4]" in capsys.readouterr().err

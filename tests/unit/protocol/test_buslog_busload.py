"""The rotating bus log (replayable, decodable) and the computed bus load."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import can
import pytest

from millctl.cli import main
from millctl.protocol import ControllerState, Heartbeat, Setpoints, default_codec
from millctl.protocol.busload import bus_load, worst_case_frame_bits
from millctl.protocol.buslog import RotatingBusLog

REPO = Path(__file__).resolve().parents[3]
CODEC = default_codec()


def heartbeats(n: int) -> list[can.Message]:
    frames = []
    for i in range(n):
        frame = CODEC.encode(Heartbeat(ControllerState.IDLE), counter=i % 16)
        frame.timestamp = 1000.0 + 0.05 * i
        frame.channel = "millbus"
        frames.append(frame)
    return frames


def test_log_rotates_by_size_and_keeps_only_the_newest_files(tmp_path: Path) -> None:
    log = RotatingBusLog(tmp_path / "records" / "bus.log", rotate_bytes=4096, keep_files=2)
    for frame in heartbeats(600):
        log.on_message_received(frame)
    log.stop()
    rotated = log.rotated_files()
    assert len(rotated) == 2
    assert (tmp_path / "records" / "bus.log").exists()
    assert all(p.stat().st_size >= 4096 for p in rotated)
    last = rotated[-1].name
    assert "#" in last and last.endswith(".log")


def test_log_is_candump_format_readable_by_python_can_and_cantools(tmp_path: Path) -> None:
    path = tmp_path / "bus.log"
    log = RotatingBusLog(path, rotate_bytes=1 << 20, keep_files=1)
    sent = [*heartbeats(3), CODEC.encode(Setpoints(120.0, 700.0, 400.0, True), counter=3)]
    for frame in sent:
        log.on_message_received(frame)
    log.stop()
    replayed = list(can.LogReader(path))
    assert [bytes(m.data) for m in replayed] == [bytes(m.data) for m in sent]
    assert [m.arbitration_id for m in replayed] == [m.arbitration_id for m in sent]
    decoded = [CODEC.decode(m) for m in replayed]
    assert all(d.crc_ok for d in decoded)
    cantools = Path(sys.executable).with_name("cantools")
    out = subprocess.run(
        [str(cantools), "decode", "--single-line", str(REPO / "config" / "millbus.dbc")],
        input=path.read_text(),
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout
    assert "Heartbeat(" in out and "controller_state: IDLE" in out
    assert "rotary_rpm: 120.0 rpm" in out


def test_log_refuses_an_unsupported_format(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"\.log \(candump\) or \.blf"):
        RotatingBusLog(tmp_path / "bus.txt", rotate_bytes=4096, keep_files=1)


def test_worst_case_frame_length_matches_davis_et_al() -> None:
    assert worst_case_frame_bits(8) == 135
    assert worst_case_frame_bits(0) == 55
    assert worst_case_frame_bits(8, extended_id=True) == 160
    with pytest.raises(ValueError):
        worst_case_frame_bits(9)


def test_bus_load_at_500_kbit_is_within_the_15_percent_target() -> None:
    load = bus_load(CODEC, 500_000, event_rate_hz=10.0)
    heartbeat = next(f for f in load.frames if f.name == "Heartbeat")
    assert heartbeat.periodic and heartbeat.rate_hz == pytest.approx(20.0)
    assert load.periodic_load == pytest.approx(sum(f.rate_hz * 135 for f in load.frames if f.periodic) / 500_000)
    assert load.periodic_load < load.total_load <= 0.15
    assert bus_load(CODEC, 125_000).total_load == pytest.approx(4 * load.total_load)


def test_bus_load_command_prints_the_figure(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--config", str(REPO / "config" / "mill.toml"), "bus", "load", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)["result"]
    assert report["bitrate_bit_s"] == 500_000
    assert report["within_target"] is True
    assert report["total_load"] == pytest.approx(bus_load(CODEC, 500_000).total_load)
    with pytest.raises(SystemExit) as caught:
        main(["bus", "load", "--bitrate", "0"])
    assert caught.value.code == 1


def test_bus_frames_command_lists_every_frame(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bus", "frames", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["result"]
    assert [r["name"] for r in rows][:3] == ["EStop", "Command", "Heartbeat"]
    assert all(r["cycle_ms"] for r in rows if r["name"] in ("Heartbeat", "Setpoints", "NodeStatus"))


def test_docs_show_the_bus_load_the_command_prints() -> None:
    text = (REPO / "docs" / "protocol.md").read_text()
    load = bus_load(CODEC, 500_000)
    expected = f"periodic frames: {load.periodic_load:.2%}; with every event frame at 10 Hz: {load.total_load:.2%}"
    assert expected in text, "docs/protocol.md is stale: paste the output of `millctl bus load` again"
    for kind in ("EStop", "Heartbeat", "SimFault"):
        assert f"| {kind} |" in text

"""``python -m firmware_sim``: starts on the virtual interface, exits 0 on SIGTERM, 1 on bad input."""

from __future__ import annotations

import signal
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from firmware_sim.__main__ import main

REPO = Path(__file__).resolve().parents[3]
CONFIG = REPO / "config" / "mill.toml"


def _command(*extra: str) -> list[str]:
    return [sys.executable, "-m", "firmware_sim", *extra]


def test_sigterm_stops_the_node_and_exits_0() -> None:
    channel = f"node-main-{uuid.uuid4().hex}"
    process = subprocess.Popen(
        _command("--config", str(CONFIG), "--interface", "virtual", "--channel", channel),
        cwd=REPO,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stderr is not None
        for line in process.stderr:
            if "node on virtual" in line:
                break
        process.send_signal(signal.SIGTERM)
        _, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 0, err
    assert "heater off" in err


def test_bad_config_exits_1(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    bad = tmp_path / "mill.toml"
    bad.write_text(CONFIG.read_text().replace("max_speed_rpm = 400.0", "max_speed_rpm = -4.0"))
    assert main(["--config", str(bad)]) == 1
    assert "max_speed_rpm" in caplog.text


def test_bad_arguments_exit_1() -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["--config", str(CONFIG), "--seed", "x"])
    assert exit_info.value.code == 1


def test_bad_interface_override_exits_1() -> None:
    assert main(["--config", str(CONFIG), "--interface", "carrier-pigeon"]) == 1

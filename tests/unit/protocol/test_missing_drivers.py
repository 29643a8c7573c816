"""Every accepted python-can interface without its library or adapter: exit 3 and a sentence naming what to install.

The machine that runs the unit tier has no vendor library, no USB adapter and
no SocketCAN device, so each interface here is the case of a new user whose
config names an adapter that is not installed (issue 39, item 1: kvaser exited
4 with ``NameError: canGetNumberOfChannels``, and the shipped unit restarts on 4).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from millctl.cli import main
from millctl.config.bus import NUMBERED_CHANNEL, known_interfaces
from millctl.config.loader import packaged_file
from millctl.errors import ExitCode
from millctl.protocol.drivers import NEEDS, SELF_CONTAINED

CHANNEL = {"socketcan": "millctl-no-such", "pcan": "PCAN_USBBUS1", "vector": "0", "slcan": "/dev/ttyACM99"}
OPTIONS = {"socketcand": '{ host = "127.0.0.1", port = 9 }'}  # the discard port: nothing listens there

NEEDING = sorted(known_interfaces() - SELF_CONTAINED)


def _config(tmp_path: Path, interface: str) -> Path:
    channel = CHANNEL.get(interface, "0" if interface in NUMBERED_CHANNEL else "/dev/ttyUSB99")
    text = packaged_file("mill.toml").read_text()
    bus = f'[bus]\ninterface = "{interface}"\nchannel = "{channel}"\nbitrate_bit_s = 500000\n'
    if interface in OPTIONS:
        bus += f"options = {OPTIONS[interface]}\n"
    start = text.index("[bus]")
    end = text.index("[service]")
    path = tmp_path / f"{interface}.toml"
    path.write_text(text[:start] + bus + "\n" + text[end:])
    return path


def test_every_interface_but_the_self_contained_ones_says_what_it_needs() -> None:
    assert set(NEEDS) == known_interfaces() - SELF_CONTAINED
    assert all("install" in text or "needs" in text or "(" in text for text in NEEDS.values())


@pytest.mark.parametrize("interface", NEEDING)
def test_bus_check_without_the_driver_exits_3_naming_what_to_install(
    interface: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = _config(tmp_path, interface)
    code = main(["--config", str(config), "bus", "check", "--listen-s", "0", "--json"])
    captured = capsys.readouterr()
    assert code == ExitCode.BUS, captured.err
    error = json.loads(captured.out)["error"]
    assert error["exit_code"] == 3
    assert f"interface {interface} needs {NEEDS[interface]}" in error["message"]
    assert f"interface {interface} needs" in captured.err
    assert "Traceback" not in captured.err


def test_one_plain_line_on_stderr_not_python_cans_warnings(tmp_path: Path) -> None:
    # a fresh process, so that python-can imports its kvaser driver (and logs its warning) here
    config = _config(tmp_path, "kvaser")
    done = subprocess.run([sys.executable, "-m", "millctl", "--config", str(config), "bus", "check", "--listen-s", "0"],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == ExitCode.BUS, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("millctl: cannot open the CAN bus"), lines
    assert "Kvaser's CANlib" in lines[0] and "unavailable" not in lines[0]


def test_serve_without_the_driver_exits_3_which_the_unit_does_not_restart(tmp_path: Path) -> None:
    config = _config(tmp_path, "kvaser")
    with tempfile.TemporaryDirectory(prefix="mc-") as run:  # short: a Unix socket's path has at most 107 bytes
        os.chmod(run, 0o700)
        env = {**os.environ, "XDG_STATE_HOME": str(tmp_path / "state"), "XDG_RUNTIME_DIR": run}
        done = subprocess.run([sys.executable, "-m", "millctl", "--config", str(config), "serve"], env=env,
                              capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == ExitCode.BUS, done.stderr
    assert "interface kvaser needs Kvaser's CANlib" in done.stderr
    unit = (Path(__file__).resolve().parents[3] / "config" / "systemd" / "millctl.service").read_text()
    assert "RestartPreventExitStatus=1 3" in unit

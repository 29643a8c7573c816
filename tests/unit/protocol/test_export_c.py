"""`millctl bus export-c`: cantools' packers and the E2E header are written, compile, and pack what millctl packs."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from millctl.cli import main
from millctl.errors import ExitCode
from millctl.protocol import ControllerState, DriveTelemetry, Heartbeat, default_codec

CC = shutil.which("cc") or shutil.which("gcc")

PROGRAM = r"""
#include <stdio.h>
#include <string.h>
#include "millbus.h"
#include "millbus_e2e.h"

static void show(const uint8_t *frame) {
    for (int i = 0; i < 8; i++) printf("%02x", frame[i]);
    printf("\n");
}

int main(void) {
    const uint8_t check[] = "123456789";
    printf("%02x\n", millbus_crc8_sae_j1850(0xFF, check, 9) ^ 0xFF);

    struct millbus_heartbeat_t heartbeat;
    memset(&heartbeat, 0, sizeof heartbeat);
    heartbeat.counter = 5;
    heartbeat.controller_state = 3;  /* RUNNING */
    heartbeat.challenge_echo = 0xBEEF;
    uint8_t frame[8];
    if (millbus_heartbeat_pack(frame, &heartbeat, sizeof frame) != 8) return 1;
    frame[0] = millbus_e2e_crc(MILLBUS_HEARTBEAT_E2E_DATA_ID, frame);
    show(frame);

    struct millbus_drive_telemetry_t drive;
    memset(&drive, 0, sizeof drive);
    drive.counter = 15;
    drive.rotary_rpm = millbus_drive_telemetry_rotary_rpm_encode(123.4);
    drive.vibration_rpm = millbus_drive_telemetry_vibration_rpm_encode(-0.3);
    drive.rotary_torque_nm = millbus_drive_telemetry_rotary_torque_nm_encode(1.2);
    if (millbus_drive_telemetry_pack(frame, &drive, sizeof frame) != 8) return 1;
    frame[0] = millbus_e2e_crc(MILLBUS_DRIVE_TELEMETRY_E2E_DATA_ID, frame);
    show(frame);
    return 0;
}
"""


def test_export_writes_the_packers_and_refuses_to_overwrite(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "firmware" / "generated"
    assert main(["bus", "export-c", str(out)]) == ExitCode.OK
    names = sorted(p.name for p in out.iterdir())
    assert names == ["millbus.c", "millbus.h", "millbus_e2e.h"]
    header = (out / "millbus.h").read_text()
    for frame in ("heartbeat", "setpoints", "command", "node_status", "drive_telemetry", "furnace_telemetry"):
        assert f"int millbus_{frame}_pack(" in header and f"int millbus_{frame}_unpack(" in header
    assert "#define MILLBUS_NODE_STATUS_E2E_DATA_ID 0x4E00u" in (out / "millbus_e2e.h").read_text()
    (out / "millbus.c").write_text("/* the firmware team's edits */")
    assert main(["bus", "export-c", str(out)]) == ExitCode.INVALID_INPUT
    assert "already there" in capsys.readouterr().err
    assert (out / "millbus.c").read_text() == "/* the firmware team's edits */", "nothing is overwritten"
    assert main(["bus", "export-c", "--force", str(out)]) == ExitCode.OK
    assert "int millbus_heartbeat_pack(" in (out / "millbus.c").read_text(), "--force writes the export again"


def test_node_export_packs_only_what_the_node_sends(tmp_path: Path) -> None:
    assert main(["bus", "export-c", "--node", "Node", str(tmp_path)]) == ExitCode.OK
    header = (tmp_path / "millbus.h").read_text()
    assert "int millbus_node_status_pack(" in header and "int millbus_heartbeat_unpack(" in header
    assert "int millbus_heartbeat_pack(" not in header


@pytest.mark.skipif(CC is None, reason="no C compiler (cc or gcc) on this machine")
def test_the_exported_c_compiles_and_packs_byte_for_byte_what_millctl_packs(tmp_path: Path) -> None:
    assert main(["bus", "export-c", str(tmp_path)]) == ExitCode.OK
    (tmp_path / "check.c").write_text(PROGRAM)
    binary = tmp_path / "check"
    compiled = subprocess.run(
        [str(CC), "-std=c99", "-Wall", "-Wextra", "-Werror", "-o", str(binary), "check.c", "millbus.c", "-lm"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )
    assert compiled.returncode == 0, compiled.stderr
    ran = subprocess.run([str(binary)], capture_output=True, text=True, timeout=30)
    assert ran.returncode == 0, ran.stderr
    crc_check, heartbeat, drive = ran.stdout.split()
    assert crc_check == "4b"
    codec = default_codec()
    assert heartbeat == bytes(codec.encode(Heartbeat(ControllerState.RUNNING, 0xBEEF), 5).data).hex()
    expected = codec.encode(DriveTelemetry(123.4, -0.3, 1.2, 0.0), 15)
    assert drive == bytes(expected.data).hex()

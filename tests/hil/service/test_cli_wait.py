"""``--wait`` on arm/set/stop/disarm, and reset answering with the state after it, against the real service.

The real ``millctl serve`` with its embedded simulated node (issue 39, item 7):
each command with ``--wait`` returns once its goal is reached and reports that
state; a goal not reached in time exits 2; ``reset`` answers with the state the
cleared trip leads to, not TRIPPED. A recipe run whose stderr is a pipe prints
plain progress lines (item 5).
"""

from __future__ import annotations

import json
from typing import Any

import pytest

from millctl.api import ControllerState
from millctl.cli import main
from millctl.errors import ExitCode
from tests.support.service import DEMO_RECIPE as DEMO
from tests.support.service import Service, run_millctl, wait_for


def _cli(service: Service, capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict[str, Any]]:
    capsys.readouterr()
    code = main(["--config", str(service.config), *argv, "--json"])
    return code, json.loads(capsys.readouterr().out)


def test_each_command_waits_for_its_goal_and_reports_the_state_reached(
    service: Service, capsys: pytest.CaptureFixture[str]
) -> None:
    code, document = _cli(service, capsys, "arm", "--wait")
    assert (code, document["result"]["state"]) == (ExitCode.OK, "ARMED")
    code, document = _cli(service, capsys, "set", "--rot-rpm", "60", "--vib-rpm", "400", "--wait")
    assert (code, document["result"]["state"]) == (ExitCode.OK, "RUNNING"), document
    with service.client() as client:
        status = client.status()
    # read again after the wait: near the targets (the drives' speed noise may pass the 3 rpm of the goal)
    assert status.measured_rotary_rpm == pytest.approx(60.0, abs=10.0)
    assert status.measured_vibration_rpm == pytest.approx(400.0, abs=10.0)
    code, document = _cli(service, capsys, "stop", "--wait")
    assert code == ExitCode.OK and document["result"]["state"] in ("ARMED", "DISABLED"), document
    with service.client() as client:
        status = client.status()
    assert status.state in (ControllerState.ARMED, ControllerState.DISABLED)
    assert abs(status.measured_rotary_rpm or 0.0) <= 10.0 and abs(status.measured_vibration_rpm or 0.0) <= 10.0
    code, document = _cli(service, capsys, "disarm", "--wait")
    assert (code, document["result"]["state"]) == (ExitCode.OK, "DISABLED")


def _armed(service: Service, capsys: pytest.CaptureFixture[str]) -> None:
    """ARMED at standstill, whatever the test before left."""
    with service.client() as client:
        state = client.status().state
    if state in (ControllerState.RUNNING, ControllerState.STOPPING):
        assert _cli(service, capsys, "stop", "--wait")[0] == ExitCode.OK
    with service.client() as client:
        state = client.status().state
    if state is not ControllerState.ARMED:
        assert _cli(service, capsys, "arm", "--wait")[0] == ExitCode.OK


def test_a_goal_not_reached_in_time_exits_2_naming_it(service: Service, capsys: pytest.CaptureFixture[str]) -> None:
    _armed(service, capsys)
    code, document = _cli(service, capsys, "set", "--rot-rpm", "120", "--vib-rpm", "800", "--wait", "0")
    assert code == ExitCode.INTERLOCK and document["ok"] is False
    assert "both drives at their targets not reached within 0 s" in document["error"]["message"]
    assert _cli(service, capsys, "stop", "--wait")[0] == ExitCode.OK
    assert _cli(service, capsys, "disarm", "--wait")[0] == ExitCode.OK


def test_reset_answers_with_the_state_after_it(service: Service, capsys: pytest.CaptureFixture[str]) -> None:
    code, document = _cli(service, capsys, "estop")
    assert (code, document["result"]["state"]) == (ExitCode.OK, "TRIPPED")
    with service.client() as client:
        wait_for(lambda: client.status().node_state == "FAULT", what="the node to report its E-stop fault")
    code, document = _reset(service, capsys)
    assert code == ExitCode.OK, document
    assert document["result"]["state"] == ControllerState.DISABLED
    capsys.readouterr()


def _reset(service: Service, capsys: pytest.CaptureFixture[str]) -> tuple[int, dict[str, Any]]:
    """``millctl reset --json``, again while the controller refuses it for drives still coasting (> 1 rpm)."""
    answer: list[tuple[int, dict[str, Any]]] = []

    def accepted() -> bool:
        answer[:] = [_cli(service, capsys, "reset")]
        code, document = answer[0]
        return code != ExitCode.INTERLOCK or "standstill" not in document["error"]["message"]

    wait_for(accepted, 30.0, "the drives at standstill, so that reset is accepted")
    return answer[0]


def test_a_piped_recipe_run_prints_plain_progress_lines(service: Service, capsys: pytest.CaptureFixture[str]) -> None:
    with service.client() as client:
        tripped = client.status().state is ControllerState.TRIPPED
    if tripped:  # a test before left a trip: clear it first
        assert _reset(service, capsys)[0] == ExitCode.OK
    # stderr is a pipe here, as under `… 2>run.log` or a CI job: no live display, plain lines instead
    done = run_millctl(service.config, "recipe", "run", str(DEMO), timeout_s=300.0)
    assert done.returncode == ExitCode.OK, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.startswith("demo: ")]
    assert "\x1b[" not in done.stderr  # no terminal codes in a log
    assert len({line.split(",")[0] for line in lines}) >= 3, done.stderr  # every step says it began
    assert any("RUNNING step 1/" in line for line in lines) and "ω_r" in lines[-1]

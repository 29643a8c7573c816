"""Recipe steps are numbered from 1 in every message: validation, pre-flight and plan alike (issue 39, item 8)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from millctl.cli import main
from millctl.errors import ExitCode

RAMP = "[[steps]]\nkind = 'ramp'\nrotary_rpm = {}\nvibration_rpm = 800\n"


def _recipe(tmp_path: Path, *steps: str) -> str:
    path = tmp_path / "r.toml"
    path.write_text("[recipe]\nname = 'r'\n" + "".join(steps))
    return str(path)


def test_the_third_step_is_step_3_in_validation_and_preflight(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    invalid = _recipe(tmp_path, RAMP.format(100), RAMP.format(120), RAMP.format("'fast'"))
    assert main(["recipe", "check", invalid]) == ExitCode.INVALID_INPUT
    err = capsys.readouterr().err
    assert "step 3 rotary_rpm = 'fast'" in err and "steps." not in err, err
    refused = _recipe(tmp_path, RAMP.format(100), RAMP.format(120), RAMP.format(250))
    assert main(["recipe", "check", refused]) == ExitCode.INTERLOCK
    assert ": step 3 at t = " in capsys.readouterr().err
    assert main(["recipe", "plan", "--json", _recipe(tmp_path, RAMP.format(100), RAMP.format(120))]) == ExitCode.OK
    steps = json.loads(capsys.readouterr().out)["result"]["steps"]
    assert [s["index"] for s in steps if s["kind"] == "ramp"] == [1, 2]

"""docs/operations.md says what the commands do: recipe check's exit codes, --wait and its defaults (issue 39, 7)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from millctl.cli import build_parser, main
from millctl.cli.wait import DEFAULT_TIMEOUT_S, GOALS
from millctl.errors import ExitCode

REPO = Path(__file__).resolve().parents[2]
OPERATIONS = (REPO / "docs" / "operations.md").read_text()


def _row(command: str) -> str:
    return next(line for line in OPERATIONS.splitlines() if line.startswith(f"| `{command}"))


def test_recipe_check_exits_as_documented(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    row = _row("millctl recipe check FILE")
    assert "exit 1 when the file is invalid" in row and "2 when the pre-flight refuses it" in row
    invalid = tmp_path / "invalid.toml"
    invalid.write_text("[recipe]\nname = 'x'\n[[steps]]\nkind = 'spin'\n")
    refused = tmp_path / "refused.toml"
    refused.write_text("[recipe]\nname = 'fast'\n[[steps]]\nkind = 'ramp'\nrotary_rpm = 250\nvibration_rpm = 800\n")
    assert main(["recipe", "check", str(invalid)]) == ExitCode.INVALID_INPUT
    assert main(["recipe", "check", str(refused)]) == ExitCode.INTERLOCK
    capsys.readouterr()


def _has_wait(parser: argparse.ArgumentParser) -> bool:
    return any("--wait" in action.option_strings for action in parser._actions)


def test_wait_is_on_the_documented_commands_with_the_documented_defaults() -> None:
    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices
    waiting = {name for name, parser in commands.items() if _has_wait(parser)}
    assert waiting == set(GOALS) == set(DEFAULT_TIMEOUT_S) == {"arm", "disarm", "stop", "set", "reset"}
    paragraph = OPERATIONS[OPERATIONS.index("**`--wait [TIMEOUT_S]`**"):][:1500]
    for command in waiting:
        assert re.search(rf"\b{command}\b", paragraph), command
    assert "arm/disarm 10 s" in paragraph and DEFAULT_TIMEOUT_S["arm"] == DEFAULT_TIMEOUT_S["disarm"] == 10.0
    assert "stop 120 s" in paragraph and DEFAULT_TIMEOUT_S["stop"] == 120.0
    assert "reset 15 s" in paragraph and DEFAULT_TIMEOUT_S["reset"] == 15.0
    assert "ramp's duration + 30 s" in paragraph and DEFAULT_TIMEOUT_S["set"] == 30.0
    assert "exit 2" in paragraph

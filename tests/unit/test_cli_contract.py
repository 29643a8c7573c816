"""The CLI's contract: JSON documents (errors too), exit codes, flags in messages, quiet broken pipes, help."""

from __future__ import annotations

import argparse
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import httpx
import pytest

from millctl.api import RecipeProgress
from millctl.cli import build_parser, main
from millctl.cli.failures import describe_failure
from millctl.cli.output import JSON_SCHEMA_VERSION, write_atomically
from millctl.client import raise_for_error
from millctl.client_errors import InterlockRefusal, RequestInvalid
from millctl.errors import ExitCode, MillctlError

REPO = Path(__file__).resolve().parents[2]


def test_every_json_output_has_the_schema_and_the_command(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["limits", "--json", "--vib-rpm", "800"]) == ExitCode.OK
    document = json.loads(capsys.readouterr().out)
    assert (document["schema"], document["command"], document["ok"]) == (JSON_SCHEMA_VERSION, "limits", True)
    row = document["result"]["rows"][0]
    assert row["vibration_rpm"] == 800.0 and row["limit_rotary_rpm"] == pytest.approx(190.0, abs=0.1)
    assert set(row["law_limit_rotary_rpm"]) >= {"paper-eq9"}


def test_one_key_scheme_no_abbreviations_or_law_names_in_keys(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["limits", "--json", "--vib-rpm", "800"]) == ExitCode.OK
    assert main(["physics", "--rot-rpm", "100", "--vib-rpm", "800", "--json"]) == ExitCode.OK
    texts = capsys.readouterr().out

    def keys(value: object) -> set[str]:
        if isinstance(value, dict):
            found = {k for k in value if not k.startswith("paper") and not k.startswith("corrected")}
            return found | {k for v in value.values() for k in keys(v)}
        if isinstance(value, list):
            return {k for v in value for k in keys(v)}
        return set()

    decoder, found, at = json.JSONDecoder(), set(), 0
    while at < len(texts.strip()):
        value, end = decoder.raw_decode(texts, at)
        found |= keys(value)
        at = end + 1
    assert not {k for k in found if k.startswith(("rot_", "vib_", "omega_")) or "-" in k}, found


def test_errors_are_json_on_stdout_with_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nobody.sock"
    code = main(["set", "--rot-rpm", "10", "--vib-rpm", "10", "--socket", str(missing), "--json"])
    assert code == ExitCode.BUS
    captured = capsys.readouterr()
    document = json.loads(captured.out)
    assert document["ok"] is False and document["command"] == "set"
    assert document["error"]["exit_code"] == 3 and "millctl serve" in document["error"]["message"]
    assert "millctl serve" in captured.err  # the human line stays on stderr


def test_refusals_exit_2_from_every_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    recipe = tmp_path / "fast.toml"
    recipe.write_text("[recipe]\nname = 'fast'\n[[steps]]\nkind = 'ramp'\nrotary_rpm = 250\nvibration_rpm = 800\n")
    assert main(["recipe", "check", str(recipe), "--json"]) == ExitCode.INTERLOCK
    error = json.loads(capsys.readouterr().out)["error"]
    assert error["exit_code"] == 2 and "exceeds the limit" in error["problems"][0]
    refusal = _raised(409, {"code": "interlock_refused", "message": "refused", "field": "omega_r"})
    assert describe_failure(refusal)[0] == ExitCode.INTERLOCK.value == 2


def _raised(status: int, body: dict[str, object]) -> MillctlError:
    """The error the client raises for this answer (one of millctl's own: a crash would fail here)."""
    with pytest.raises(MillctlError) as raised:
        raise_for_error(httpx.Response(status, json=body), "service socket /x")
    return raised.value


def test_messages_name_the_cli_flag_not_the_api_field() -> None:
    invalid = RequestInvalid("body.rotary_rpm: Input should be greater than or equal to 0", "body.rotary_rpm")
    code, message, error = describe_failure(invalid)
    assert code == ExitCode.INVALID_INPUT and "--rot-rpm" in message and "body." not in message
    assert error["flag"] == "--rot-rpm"
    refusal = _raised(409, {"code": "interlock_refused", "message": "ω_r = 250.0 rpm exceeds the limit",
                            "refusals": [{"quantity": "omega_r", "value": 250.0, "limit": 190.0, "unit": "rpm",
                                          "reason": "exceeds"}]})
    assert isinstance(refusal, InterlockRefusal)
    assert describe_failure(refusal)[2]["refusals"][0]["flag"] == "--rot-rpm"


def test_ctrl_c_does_not_reuse_the_refusal_code(monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    def interrupted(args: argparse.Namespace) -> dict[str, object]:
        raise KeyboardInterrupt

    monkeypatch.setattr("millctl.cli.limits_cmd.limits_table", interrupted)
    code = main(["limits", "--json"])
    assert code == ExitCode.INTERRUPTED.value == 130 and code != ExitCode.INTERLOCK
    assert json.loads(capsys.readouterr().out)["error"]["code"] == "interrupted"


def test_a_closed_pipe_ends_quietly() -> None:
    # `millctl bus frames | head -1`: the reader leaves early; no traceback, exit 141
    command = f"{sys.executable} -m millctl bus frames | head -c 20 >/dev/null; exit ${{PIPESTATUS[0]}}"
    done = subprocess.run(["bash", "-c", command], capture_output=True, text=True, timeout=60, cwd=REPO,
                          env={**os.environ, "COLUMNS": "80"}, check=False)
    assert done.stderr == ""
    assert done.returncode in (ExitCode.OK, ExitCode.BROKEN_PIPE)  # OK only if it all fit in the pipe at once
    big = f"{sys.executable} -m millctl limits --json | head -c 20 >/dev/null; exit ${{PIPESTATUS[0]}}"
    done = subprocess.run(["bash", "-c", big], capture_output=True, text=True, timeout=60, cwd=REPO, check=False)
    assert "Traceback" not in done.stderr and "BrokenPipe" not in done.stderr


def _walk(parser: argparse.ArgumentParser, path: str = "millctl") -> list[tuple[str, argparse.ArgumentParser]]:
    found = [(path, parser)]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found += _walk(sub, f"{path} {name}")
    return found


def test_every_command_and_argument_has_help() -> None:
    top = build_parser()
    helps = {a.dest: a.help for a in top._subparsers._group_actions[0]._choices_actions}  # type: ignore[union-attr]
    missing = [f"command {name}" for name, text in helps.items() if not text]
    for path, parser in _walk(top):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                missing += [f"{path} {c.dest}" for c in action._choices_actions if not c.help]
            elif not action.help and action.dest != "help":
                missing.append(f"{path} {action.option_strings or action.dest}")
    assert missing == []


def test_shell_completion(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["completion", "bash"]) == ExitCode.OK
    script = capsys.readouterr().out
    assert "millctl" in script and "--rot-rpm" in script


def _write_png(path: Path) -> None:
    path.write_bytes(b"png")


def test_figures_are_written_with_the_users_umask(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        write_atomically(tmp_path / "fig.png", _write_png)
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "fig.png").stat().st_mode) == 0o644


def test_config_show_prints_modes_in_octal(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "show"]) == ExitCode.OK
    assert "socket_mode = 0o600  # default" in capsys.readouterr().out.splitlines()  # in [service], as TOML


def test_docs_name_no_file_a_user_does_not_have() -> None:
    for doc in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        assert "../shared/" not in doc.read_text(), doc


def _progress(**changes: object) -> RecipeProgress:
    base = {"run_id": "r", "recipe": "demo", "recipe_file": "demo.toml", "state": "RUNNING", "reason": "",
            "step": 2, "steps": 4, "kind": "hold", "elapsed_s": 10.0, "step_elapsed_s": 1.0, "remaining_s": 30.0,
            "record": "x.jsonl"}
    return RecipeProgress.model_validate({**base, **changes})


def test_recipe_run_progress_never_shows_none_and_counts_the_stop_down(monkeypatch: pytest.MonkeyPatch) -> None:
    from millctl.cli import recipe_run_cmd as cmd

    assert cmd._step(_progress()) == "step 2/4 (hold)"
    stopping = _progress(state="STOPPING", step=4, kind=None, remaining_s=8.0)
    assert "None" not in cmd._line(stopping) and "stopping" in cmd._step(stopping)
    now = [100.0]
    monkeypatch.setattr("millctl.cli.recipe_run_cmd.time.monotonic", lambda: now[0])
    clock = cmd._StopClock()
    assert clock.remaining_s(stopping) == 8.0
    now[0] += 3.0
    assert clock.remaining_s(stopping) == 5.0  # the service's figure stays at 8

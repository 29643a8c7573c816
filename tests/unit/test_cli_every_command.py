"""Every command, run as a script would: ``--json`` gives one JSON document of one envelope; ``| head`` gives 141.

The table names arguments for every command the parser has (a new command
without an entry fails the first test), chosen so that each ends quickly and
offline: a missing service socket, a missing file, a refused recipe, or real
work that needs no service (issue 39, items 2 and 3).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from millctl.cli import build_parser, main
from millctl.cli.output import JSON_SCHEMA_VERSION
from millctl.errors import ExitCode

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "config" / "mill.toml"
DEMO = REPO / "config" / "recipes" / "demo.toml"


def _commands(tmp: Path) -> dict[str, tuple[list[str], ExitCode]]:
    """Command → (arguments after it, expected exit code); the files they name are written into ``tmp``."""
    nobody = ["--socket", str(tmp / "nobody.sock")]
    fast = tmp / "fast.toml"
    if tmp.is_dir():
        fast.write_text("[recipe]\nname = 'fast'\n[[steps]]\nkind = 'ramp'\nrotary_rpm = 250\nvibration_rpm = 800\n")
        (tmp / "bad.toml").write_text("[bus]\ninterface = 'virtaul'\n")
    ok, bus, invalid, refused = ExitCode.OK, ExitCode.BUS, ExitCode.INVALID_INPUT, ExitCode.INTERLOCK
    return {
        "config show": ([], ok),
        "config check": ([str(CONFIG)], ok),
        "limits": (["--vib-rpm", "800"], ok),
        "physics": (["--rot-rpm", "100", "--vib-rpm", "800"], ok),
        "recipe check": ([str(DEMO)], ok),
        "recipe plan": ([str(DEMO)], ok),
        "recipe run": ([str(fast), *nobody], refused),  # refused by the pre-flight: nothing starts
        "recipe pause": (nobody, bus),
        "recipe list": (nobody, bus),
        "recipe resume": (["r1", *nobody], bus),
        "recipe abort": (["r1", *nobody], bus),
        "recipe status": (nobody, bus),
        "study": ([str(tmp / "no-such-study.toml")], invalid),
        "bus load": ([], ok),
        "bus frames": ([], ok),
        "bus log convert": ([str(tmp / "no-such.log"), str(tmp / "out.asc")], invalid),
        "bus log show": ([str(tmp / "no-such.log")], invalid),
        "bus monitor": (["--duration-s", "0.2"], ok),  # the virtual bus opens; nothing is heard
        "bus check": (["--listen-s", "0"], bus),  # the virtual bus opens; no node answers on it
        "bus export-c": ([str(tmp / "c")], ok),
        "serve": (["--socket", str(tmp / "s.sock")], invalid),  # with bad.toml (_full): ends at once
        "status": (nobody, bus),
        "set": (["--rot-rpm", "10", "--vib-rpm", "10", *nobody], bus),
        "arm": (nobody, bus),
        "disarm": (nobody, bus),
        "stop": (nobody, bus),
        "estop": (nobody, bus),
        "reset": (nobody, bus),
        "watch": (nobody, invalid),  # interactive: no JSON form, refused as one document
        "tui": (nobody, invalid),
        "report": ([str(tmp / "no-such-run.jsonl")], invalid),
        "bench": (["--no-such-option"], invalid),
        "completion": (["bash"], ok),
    }


def _leaves(parser: argparse.ArgumentParser, path: str = "") -> Iterator[str]:
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield path.strip()
    for action in subs:
        for name, sub in action.choices.items():
            yield from _leaves(sub, f"{path} {name}")


def test_the_table_has_every_command(tmp_path: Path) -> None:
    assert set(_leaves(build_parser())) == set(_commands(tmp_path))


def _full(command: str, tmp: Path, *, json_flag: bool = True) -> list[str]:
    rest = _commands(tmp)[command][0]
    config = ["--config", str(tmp / "bad.toml")] if command == "serve" else []
    return [*config, *command.split(), *rest, *(["--json"] if json_flag else [])]


@pytest.mark.parametrize("command", sorted(_commands(Path("/nonexistent-millctl"))))
def test_every_command_with_json_prints_one_document(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    expected = _commands(tmp_path)[command][1]
    try:
        code = main(_full(command, tmp_path))
    except SystemExit as exited:  # an argument error
        code = int(exited.code or 0)
    out = capsys.readouterr().out
    assert code == expected, out
    document = json.loads(out)  # exactly one document: anything else on stdout fails here
    assert document["schema"] == JSON_SCHEMA_VERSION and document["command"] == command
    assert document["ok"] is (code == ExitCode.OK)
    if code == ExitCode.OK:
        assert "result" in document
    else:
        assert document["error"]["exit_code"] == code and document["error"]["message"]


@pytest.mark.parametrize(
    "argv",
    [
        ["physics", "--json", "--rot-rpm", "-100", "--vib-rpm", "800"],
        ["set", "--json", "--rot-rpm", "ten", "--vib-rpm", "800"],
        ["bus", "log", "convert", "--json"],
        ["config", "--json"],
    ],
)
def test_argument_errors_with_json_are_one_document(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exited:
        main(argv)
    assert exited.value.code == ExitCode.INVALID_INPUT
    captured = capsys.readouterr()
    document = json.loads(captured.out)
    assert document["ok"] is False and document["error"]["exit_code"] == 1
    assert document["command"] == " ".join(w for w in argv if not w.startswith("-") and w[0].isalpha()
                                           and w not in ("ten",))
    assert "usage:" in captured.err  # the human form stays on stderr


@contextlib.contextmanager
def closed_stdout() -> Iterator[None]:
    """stdout is a pipe whose reader has gone (``| head`` after its line), before the command writes.

    Entered in the test's body: pytest puts its own capture back on sys.stdout before the test runs.
    """
    read_end, write_end = os.pipe()
    os.close(read_end)
    stream = os.fdopen(write_end, "w")
    saved = sys.stdout
    sys.stdout = stream
    try:
        yield
    finally:
        sys.stdout = saved
        with contextlib.suppress(BrokenPipeError):
            stream.close()


def _piped(argv: list[str]) -> int:
    with closed_stdout():
        try:
            return main(argv)
        except SystemExit as exited:  # an argument error
            return int(exited.code or 0)


PRINTING = ["config show", "config check", "limits", "physics", "recipe check", "recipe plan", "bus load",
            "bus frames", "bus export-c", "completion"]
"""The commands that print data on stdout without --json."""


@pytest.mark.parametrize("command", PRINTING)
def test_a_reader_that_left_gives_141(command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert _piped(_full(command, tmp_path, json_flag=False)) == ExitCode.BROKEN_PIPE


@pytest.mark.parametrize("command", sorted(_commands(Path("/nonexistent-millctl"))))
def test_a_reader_that_left_gives_141_with_json_too(command: str, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert _piped(_full(command, tmp_path)) == ExitCode.BROKEN_PIPE

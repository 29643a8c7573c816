"""The CLI starts without its heavy parts, and refuses a bad file before loading them (issue 37, item 5).

The real CLI in a fresh interpreter under ``python -X importtime``, which names
every module the process imported: ``/dev/zero``, a FIFO and TOML nested 50,000
deep get exit 1 and a message naming the file without numpy, numba, scipy or
pydantic ever loading (on the old code each refusal came after all of them: 3 to
8 s on a loaded host); ``--help`` and ``--version`` load none of numpy, pydantic,
httpx, python-can or rich, and ``status``, ``stop`` and ``estop`` none of numpy,
numba or scipy. What it costs in seconds is ``python -m bench.startup``'s to
print (docs/safety.md), never asserted here.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from millctl.cli.precheck import MAX_TOML_DEPTH, check_toml_file
from millctl.config.loader import MAX_TOML_DEPTH as LOADER_MAX_TOML_DEPTH
from millctl.config.loader import read_toml
from millctl.errors import ConfigError, RecipeError
from tests.support.pace import stretched
from tests.support.service import REPO

CLI_TIMEOUT_S = 60.0
"""A safety net for one CLI run (stretched with load), not a bound: what is asserted is what was imported."""
ADDRESS_SPACE_BYTES = 4 << 30
"""The CLI runs with at most this much address space: a file read whole fails, never swaps."""
NESTED = 50_000
COMPUTE = ("numpy", "numba", "scipy")
"""Loaded by the physics, the planner and the studies: never before a refusal, never for a client command."""


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE_BYTES, ADDRESS_SPACE_BYTES))


def _cli(tmp_path: Path, *args: str) -> tuple[subprocess.CompletedProcess[str], set[str]]:
    """Run ``python -X importtime -m millctl ARGS``; its result (stderr without the import lines) and its imports."""
    env = {k: v for k, v in os.environ.items() if k != "MILLCTL_CONFIG"}
    try:
        done = subprocess.run([sys.executable, "-X", "importtime", "-m", "millctl", *args], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=stretched(CLI_TIMEOUT_S), check=False,
                              preexec_fn=_limit_memory)
    except subprocess.TimeoutExpired:
        pytest.fail(f"millctl {' '.join(args)} did not end within {stretched(CLI_TIMEOUT_S):.0f} s")
    imported: set[str] = set()
    said: list[str] = []
    for line in done.stderr.splitlines():
        if line.startswith("import time:"):
            imported.add(line.rsplit("|", 1)[-1].strip())
        else:
            said.append(line)
    assert "millctl.cli" in imported, "python -X importtime named no module: the check would be empty"
    return subprocess.CompletedProcess(done.args, done.returncode, done.stdout, "\n".join(said)), imported


def _roots(imported: set[str]) -> set[str]:
    return {name.split(".")[0] for name in imported}


def _fifo(tmp_path: Path) -> Path:
    path = tmp_path / "fifo.toml"
    os.mkfifo(path)
    return path


def _nested(tmp_path: Path) -> Path:
    path = tmp_path / "nested.toml"
    path.write_text("a = " + "[" * NESTED + "]" * NESTED + "\n", encoding="utf-8")
    return path


FILES: dict[str, tuple[Callable[[Path], Path], str]] = {
    "dev_zero": (lambda tmp_path: Path("/dev/zero"), "a character device, not a regular file"),
    "fifo": (_fifo, "a FIFO (named pipe), not a regular file"),
    "nested": (_nested, "arrays or inline tables nested too deeply: the bound is"),
}
COMMANDS: dict[str, Callable[[Path], tuple[str, ...]]] = {
    "recipe_check": lambda path: ("recipe", "check", str(path)),
    "recipe_run": lambda path: ("recipe", "run", str(path), "--socket", "nobody.sock"),
    "config_check": lambda path: ("config", "check", str(path)),
    "study": lambda path: ("study", str(path)),
    "config_option": lambda path: ("--config", str(path), "status", "--socket", "nobody.sock"),
}


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize("kind", list(FILES))
def test_a_bad_file_is_refused_before_numpy_numba_scipy_or_pydantic_load(
    tmp_path: Path, kind: str, command: str
) -> None:
    make, reason = FILES[kind]
    path = make(tmp_path)
    done, imported = _cli(tmp_path, *COMMANDS[command](path))
    assert done.returncode == 1, (done.returncode, done.stderr[-2000:])
    assert f"{path}: " in done.stderr and reason in done.stderr, done.stderr[-2000:]
    assert "Traceback" not in done.stderr
    assert not _roots(imported) & {*COMPUTE, "pydantic"}, sorted(_roots(imported) & {*COMPUTE, "pydantic"})


def test_the_refusal_is_a_json_document_too(tmp_path: Path) -> None:
    done, imported = _cli(tmp_path, "recipe", "check", "/dev/zero", "--json")
    assert done.returncode == 1
    assert '"ok": false' in done.stdout and "/dev/zero: a character device" in done.stdout
    assert not _roots(imported) & set(COMPUTE)


@pytest.mark.parametrize("args", [("--help",), ("--version",), ("recipe", "--help"), ("serve", "--help")])
def test_help_loads_no_heavy_dependency(tmp_path: Path, args: tuple[str, ...]) -> None:
    done, imported = _cli(tmp_path, *args)
    assert done.returncode == 0, done.stderr[-2000:]
    heavy = _roots(imported) & {*COMPUTE, "pydantic", "httpx", "can", "rich", "textual", "canopen", "cantools"}
    assert not heavy, sorted(heavy)


@pytest.mark.parametrize("command", ["status", "stop", "estop"])
def test_the_client_commands_load_no_compute_library(tmp_path: Path, command: str) -> None:
    done, imported = _cli(tmp_path, command, "--socket", str(tmp_path / "nobody.sock"))
    assert done.returncode == 3, done.stderr[-2000:]  # no service there: a bus/service error, said in words
    assert "no millctl service on socket" in done.stderr
    assert not _roots(imported) & set(COMPUTE), sorted(_roots(imported) & set(COMPUTE))


def test_a_lazy_choice_is_still_checked_and_listed(tmp_path: Path) -> None:
    done, _ = _cli(tmp_path, "limits", "--law", "no_such_law")
    assert done.returncode == 1
    assert "invalid choice: 'no_such_law'" in done.stderr and "paper-eq9" in done.stderr, done.stderr[-2000:]
    shown, _ = _cli(tmp_path, "limits", "--help")
    assert shown.returncode == 0 and "paper-eq9" in shown.stdout and "double" in shown.stdout


def test_the_early_check_has_the_loaders_bound() -> None:
    assert MAX_TOML_DEPTH == LOADER_MAX_TOML_DEPTH


def _deep(depth: int) -> str:
    return "a = " + "[" * (depth - 1) + "1" + "]" * (depth - 1) + "\n"


TEXTS: dict[str, str | bytes] = {
    "syntax": "a = [1, 2\n",
    "not_utf8": b"name = \"\xff\"\n",
    "one_past_the_bound": _deep(MAX_TOML_DEPTH + 1),
    "nested": "a = " + "[" * NESTED + "]" * NESTED + "\n",
}


@pytest.mark.parametrize("error", [ConfigError, RecipeError])
@pytest.mark.parametrize("name", list(TEXTS))
def test_the_early_check_refuses_what_the_loader_refuses_in_the_same_words(
    tmp_path: Path, name: str, error: type[ConfigError] | type[RecipeError]
) -> None:
    path = tmp_path / f"{name}.toml"
    text = TEXTS[name]
    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8"))
    with pytest.raises(error) as early:
        check_toml_file(path, error)
    with pytest.raises(error) as loader:
        read_toml(path, error)
    assert early.value.problems == loader.value.problems


def test_a_file_within_the_bound_passes_the_early_check_as_the_loader_reads_it(tmp_path: Path) -> None:
    path = tmp_path / "deep.toml"
    path.write_text(_deep(MAX_TOML_DEPTH), encoding="utf-8")
    assert check_toml_file(path, ConfigError) == read_toml(path)[0]
    for recipe in sorted((REPO / "config" / "recipes").glob("*.toml")):
        assert check_toml_file(recipe, RecipeError) == read_toml(recipe, RecipeError)[0]

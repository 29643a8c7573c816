"""Files a user names are regular files under a bound, and TOML nests a bounded depth (issue 37, defects 4 and 5).

The real CLI, as a subprocess under an address-space limit: ``/dev/zero``, a FIFO, a directory, a file over the
bound and TOML nested 50,000 deep each get exit 1 and a message naming the file and what is wrong with it. On the
old code ``/dev/zero`` was read whole (MemoryError under the limit: exit 4), the FIFO hung (the subprocess
timeout), and the nested TOML was a RecursionError (exit 4).
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import httpx
import pytest

from millctl.config.loader import packaged_file
from millctl.files import MAX_INPUT_BYTES, FileRefused, read_input_file
from millctl.service import create_app
from tests.support.pace import stretched
from tests.support.service import REPO, stepped_runtime

ADDRESS_SPACE_BYTES = 4 << 30
"""The CLI runs with at most this much address space: reading /dev/zero whole fails (MemoryError), never swaps."""
CLI_TIMEOUT_S = 60.0
"""A safety net for one CLI run (stretched with load): the old code hung on the FIFO until it."""
NESTED = 50_000


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE_BYTES, ADDRESS_SPACE_BYTES))


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    try:
        return subprocess.run([sys.executable, "-m", "millctl", *args], cwd=REPO, capture_output=True, text=True,
                              timeout=stretched(CLI_TIMEOUT_S), check=False, preexec_fn=_limit_memory)
    except subprocess.TimeoutExpired:
        pytest.fail(f"millctl {' '.join(args)} did not end within {stretched(CLI_TIMEOUT_S):.0f} s")


def _dev_zero(tmp_path: Path) -> Path:
    return Path("/dev/zero")


def _fifo(tmp_path: Path) -> Path:
    path = tmp_path / "fifo.toml"
    os.mkfifo(path)
    return path


def _directory(tmp_path: Path) -> Path:
    path = tmp_path / "dir.toml"
    path.mkdir()
    return path


def _huge(tmp_path: Path) -> Path:
    path = tmp_path / "huge.toml"
    with path.open("wb") as out:
        out.truncate(8 << 30)  # sparse: 8 GiB of size, no disk
    return path


def _nested(tmp_path: Path) -> Path:
    path = tmp_path / "nested.toml"
    path.write_text("a = " + "[" * NESTED + "]" * NESTED + "\n", encoding="utf-8")
    return path


FILES: dict[str, tuple[Callable[[Path], Path], str]] = {
    "dev_zero": (_dev_zero, "a character device, not a regular file"),
    "fifo": (_fifo, "a FIFO (named pipe), not a regular file"),
    "directory": (_directory, "a directory, not a regular file"),
    "huge": (_huge, f"{8 << 30} bytes, over the bound of {MAX_INPUT_BYTES} bytes"),
    "nested": (_nested, "arrays or inline tables nested too deeply: the bound is"),
}
COMMANDS: dict[str, Callable[[Path], tuple[str, ...]]] = {
    "recipe_check": lambda path: ("recipe", "check", str(path)),
    "config_check": lambda path: ("config", "check", str(path)),
    "config_option": lambda path: ("--config", str(path), "limits"),
}


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize("kind", list(FILES))
def test_a_file_that_is_no_regular_file_under_the_bound_is_exit_1_naming_it(
    tmp_path: Path, kind: str, command: str
) -> None:
    make, reason = FILES[kind]
    path = make(tmp_path)
    done = _cli(*COMMANDS[command](path))
    assert done.returncode == 1, (done.returncode, done.stderr[-2000:])
    assert f"{path}: " in done.stderr and reason in done.stderr, done.stderr[-2000:]
    assert "Traceback" not in done.stderr


def test_a_study_file_is_read_by_the_same_rule(tmp_path: Path) -> None:
    done = _cli("study", "/dev/zero")
    assert done.returncode == 1, (done.returncode, done.stderr[-2000:])
    assert "/dev/zero: a character device, not a regular file" in done.stderr


def test_the_reader_reads_at_most_the_bound_plus_one_byte(tmp_path: Path) -> None:
    path = tmp_path / "exact.toml"
    path.write_bytes(b"x" * 100)
    assert read_input_file(path, max_bytes=100) == b"x" * 100
    with pytest.raises(FileRefused, match=r"100 bytes, over the bound of 99 bytes"):
        read_input_file(path, max_bytes=99)
    with pytest.raises(FileRefused, match="no such file") as missing:
        read_input_file(tmp_path / "absent.toml")
    assert missing.value.missing


def test_the_packaged_configuration_and_the_shipped_recipes_nest_within_the_bound() -> None:
    from millctl.config import load_config
    from millctl.recipes import load_recipe

    load_config(packaged_file("mill.toml"))
    for recipe in sorted((REPO / "config" / "recipes").glob("*.toml")):
        load_recipe(recipe)


async def test_nested_toml_sent_to_the_recipe_check_is_a_problem_named_not_a_server_error(tmp_path: Path) -> None:
    """The check answers every recipe it cannot take with 200 and its problems (the TUI lists them); the run: 4xx."""
    runtime = stepped_runtime(tmp_path)
    text = "a = " + "[" * NESTED + "]" * NESTED + "\n"
    try:
        transport = httpx.ASGITransport(app=create_app(runtime))
        async with httpx.AsyncClient(transport=transport, base_url="http://mill") as client:
            checked = await client.post("/v1/recipe/check", json={"name": "deep.toml", "text": text})
            lease = runtime.leases.take("api:test")[0].lease_id
            run = await client.post("/v1/recipe/run", json={"name": "deep.toml", "text": text},
                                    headers={"X-Millctl-Lease": lease})
    finally:
        runtime.close()
    assert checked.status_code == 200, checked.text
    body = checked.json()
    assert not body["ok"] and any("deep.toml: arrays or inline tables nested too deeply" in p for p in body["problems"])
    assert 400 <= run.status_code < 500, run.text
    assert "nested too deeply" in run.text

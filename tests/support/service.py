"""Fixtures: a real ``millctl serve`` subprocess (embedded simulated node) on a temporary socket and records dir.

Every service started here is stopped at teardown (SIGTERM, then SIGKILL
after a bound), and its socket and records live in temporary directories.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from millctl.client import Client
from millctl.config.loader import packaged_file
from tests.support.pace import Deadline, stretched
from tests.support.realtime import popen as realtime_popen

if TYPE_CHECKING:
    from millctl.service import ServiceRuntime
    from tests.support.realtime import Role

REPO = Path(__file__).resolve().parents[2]
DEMO_RECIPE = REPO / "config" / "recipes" / "demo.toml"
"""The shipped demo recipe: under a minute at reduced speeds, then a short run near the paper's point."""
START_TIMEOUT_S = 30.0
"""A safety net for start-up, not a measurement; it stretches with load (tests.support.pace)."""
STOP_TIMEOUT_S = 30.0
UNBUFFERED = {**os.environ, "PYTHONUNBUFFERED": "1"}
"""The environment of the processes started here: unbuffered, so a failure shows everything they printed."""


def write_config(directory: Path, **service: object) -> Path:
    """A copy of the packaged config with its own virtual channel and ``[service]`` pointing into ``directory``."""
    text = packaged_file("mill.toml").read_text(encoding="utf-8")
    text = re.sub(r'(?m)^channel = ".*"$', f'channel = "svc-{uuid.uuid4().hex[:8]}"', text)
    head, _, _ = text.partition("[service]")
    values = {"socket_path": str(directory / "mill.sock"), "records_dir": str(directory / "records"), **service}
    lines = []
    for key, value in values.items():
        lines.append(f'{key} = "{value}"' if isinstance(value, str) else f"{key} = {value}")
    path = directory / "mill.toml"
    path.write_text(head + "[service]\n" + "\n".join(lines) + "\n", encoding="utf-8")
    return path


@dataclass
class Service:
    """A running ``millctl serve`` process and where it lives."""

    proc: subprocess.Popen[bytes]
    config: Path
    socket: Path
    records: Path
    log: Path

    def client(self, name: str = "test") -> Client:
        """A client of this service."""
        return Client(self.socket, name=name)

    def output(self) -> str:
        """What the service wrote to stdout and stderr."""
        return self.log.read_text(errors="replace")

    def stop(self, sig: int = signal.SIGTERM) -> int:
        """Signal the service and wait for it (SIGKILL after a bound that stretches with load); return its exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        deadline = Deadline(STOP_TIMEOUT_S)
        while (rc := self.proc.poll()) is None and not deadline.expired():
            time.sleep(0.05)
        if rc is not None:
            return rc
        self.proc.kill()
        self.proc.wait()
        pytest.fail(f"the service did not stop within {deadline.describe()}:\n{self.output()[-2000:]}")


def run_millctl(
    config: Path, *args: str, timeout_s: float = 60.0, realtime: Role | None = None
) -> subprocess.CompletedProcess[str]:
    """Run ``millctl --config CONFIG ARGS…`` and capture its output.

    ``realtime="controller"``: at the controller's real-time policy (tests/support/realtime.py), for a command
    that is the controller itself (``recipe run`` starting its embedded service and node when none runs): at
    the normal policy a loaded host delays its control loop past the node's watchdog, which then trips the
    mill, correctly (seen: its final stop tripped WATCHDOG with both hil tiers and two other jobs running).
    """
    argv = [sys.executable, "-m", "millctl", "--config", str(config), *args]
    if realtime is None:
        return subprocess.run(argv, cwd=REPO, capture_output=True, text=True, timeout=stretched(timeout_s),
                              check=False)
    proc = realtime_popen(argv, realtime=realtime, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        out, err = proc.communicate(timeout=stretched(timeout_s))
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise
    return subprocess.CompletedProcess(argv, proc.returncode, out.decode(), err.decode())


def start_service(
    directory: Path, *, wait_for_node: bool = True, module_args: list[str] | None = None, what: str = "millctl serve"
) -> Service:
    """Start ``millctl serve`` (or ``python -m MODULE_ARGS…``) with the config in ``directory``.

    Returns once the API answers (and, with ``wait_for_node``, the node is seen).
    """
    config = directory / "mill.toml"
    log = directory / "serve.log"
    argv = module_args if module_args is not None else ["millctl", "--config", str(config), "serve"]
    with log.open("wb") as out:
        proc = realtime_popen(  # at the real-time policy .ci/test gives the hil tiers, where it could
            [sys.executable, "-m", *argv],
            realtime="controller",
            cwd=REPO,
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=subprocess.STDOUT,
            env=UNBUFFERED,
        )
    service = Service(proc, config, directory / "mill.sock", directory / "records", log)
    deadline = Deadline(START_TIMEOUT_S)
    last = "no socket yet"
    while not deadline.expired():
        if proc.poll() is not None:
            pytest.fail(f"{what} exited with {proc.returncode}:\n{service.output()}")
        if service.socket.exists():
            try:
                with service.client() as client:
                    state = client.status().state
            except Exception as exc:  # not answering yet: keep the reason for the message
                last = f"status request failed: {exc}"
            else:
                if not wait_for_node or state == "DISABLED":
                    return service
                last = f"controller state {state}"
        time.sleep(0.1)
    service.stop(signal.SIGKILL)
    pytest.fail(f"{what} did not come up within {deadline.describe()} (last: {last}):\n{service.output()}")


@contextlib.contextmanager
def private_dir() -> Iterator[Path]:
    """A short temporary directory (Unix socket paths are limited to 107 bytes), removed afterwards."""
    path = Path(tempfile.mkdtemp(prefix="millctl-svc-"))
    try:
        yield path
    finally:
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture(scope="module")
def service() -> Iterator[Service]:
    """One service for a test module; stopped (and checked to be gone) at teardown."""
    with private_dir() as directory:
        os.chmod(directory, 0o755)  # traversable by anyone: the socket's own mode must keep others out
        write_config(directory)
        running = start_service(directory)
        try:
            yield running
        finally:
            running.stop()


def wait_for(condition: Callable[[], object], timeout_s: float = 10.0, what: str = "condition") -> None:
    """Poll ``condition()`` until true; fail after ``timeout_s`` (a safety net that stretches with load)."""
    deadline = Deadline(timeout_s)
    while not deadline.expired():
        if condition():
            return
        time.sleep(0.05)
    pytest.fail(f"timed out after {deadline.describe()} waiting for {what}")


# --- a runtime stepped by hand (unit tier): no loop thread, no timing --------------------------------------------
NODE_SEEN_WITHIN_S = 1.0
"""Mill time within which the controller hears the embedded node (s): its status is sent at 10 Hz."""


def advance(runtime: ServiceRuntime, seconds: float) -> None:
    """Tick controller, recipe runner and embedded node through ``seconds`` of mill time, as the loop would."""
    from millctl.clock import ManualClock

    clock = runtime.clock
    assert isinstance(clock, ManualClock)
    period_s = runtime.config.timing.controller_tick_s
    for _ in range(round(seconds / period_s)):
        runtime.tick()
        clock.advance(period_s)


def stepped_runtime(directory: Path) -> ServiceRuntime:
    """A runtime with the embedded node on a manual clock, its loop not started, once it has heard the node."""
    from millctl.clock import ManualClock
    from millctl.config import load_config
    from millctl.controller import ControllerState
    from millctl.service import ServiceRuntime

    runtime = ServiceRuntime(load_config(write_config(directory)), clock=ManualClock())
    advance(runtime, NODE_SEEN_WITHIN_S)
    assert runtime.controller.state is ControllerState.DISABLED, runtime.controller.state
    return runtime

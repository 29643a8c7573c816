"""``millctl tui --sim``: the embedded default service and simulated node, in a subprocess, for a demo.

The service runs as ``python -m millctl.tui.sim`` (``millctl serve`` with its
socket and records moved into a private temporary directory and TCP off), in
its own process so that its 100 Hz control loop never shares an interpreter
lock with the screen. :class:`SimService` starts it, waits until the node
answers, and on exit stops it with SIGTERM (a controlled stop) and removes
the directory.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from types import TracebackType

from millctl.api import ControllerState
from millctl.errors import BusError

START_TIMEOUT_S = 30.0
"""How long the service may take to come up with its node (s)."""
STOP_TIMEOUT_S = 45.0
"""How long a controlled stop may take before the service is killed (s; the service's own bound is 30 s)."""
ORPHAN_CHECK_S = 1.0
"""How often the simulated service checks that the TUI which started it is still there (s)."""


class SimService:
    """A private ``millctl serve`` with the simulated node, for the lifetime of a ``with`` block."""

    def __init__(self, config: str | None = None, *, fault_injection: bool = False) -> None:
        self.config = config
        self.fault_injection = fault_injection
        self.directory = Path(tempfile.mkdtemp(prefix="millctl-tui-"))
        self.socket_path = str(self.directory / "mill.sock")
        self.log_path = self.directory / "serve.log"
        self.proc: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> SimService:
        self.start()
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self.stop()

    def start(self) -> None:
        """Start the service and return once its node answers (or raise :class:`BusError` with its log)."""
        from millctl.client import Client

        command = [sys.executable, "-m", "millctl.tui.sim", "--dir", str(self.directory)]
        if self.config:
            command += ["--config", self.config]
        if self.fault_injection:
            command.append("--fault-injection")
        with self.log_path.open("wb") as out:
            self.proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                         start_new_session=True)  # the terminal's signals are the TUI's to handle
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise BusError(f"the simulated service exited with {self.proc.returncode}: {self.output()[-800:]}")
            if Path(self.socket_path).exists():
                with contextlib.suppress(BusError), Client(self.socket_path, name="tui-sim") as client:
                    if client.status().state is not ControllerState.DISCONNECTED:
                        return
            time.sleep(0.1)
        self.stop()
        raise BusError(f"the simulated service did not come up within {START_TIMEOUT_S:.0f} s: {self.output()[-800:]}")

    def output(self) -> str:
        """What the service wrote."""
        try:
            return self.log_path.read_text(errors="replace")
        except OSError:
            return ""

    def stop(self) -> int | None:
        """Stop the service (SIGTERM: controlled stop; SIGKILL after the bound), remove its directory; its exit code."""
        code = None
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.send_signal(signal.SIGTERM)
            try:
                code = self.proc.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                code = self.proc.wait()
        shutil.rmtree(self.directory, ignore_errors=True)
        return code


def main(argv: list[str] | None = None) -> int:
    """Serve the (given or default) config with the socket and records in ``--dir`` and TCP off."""
    from millctl.config import load_config
    from millctl.service import serve

    parser = argparse.ArgumentParser(prog="python -m millctl.tui.sim", description=__doc__)
    parser.add_argument("--dir", required=True, help="private directory for the socket and records")
    parser.add_argument("--config", help="mill configuration (TOML)")
    parser.add_argument("--fault-injection", action="store_true", help="let the TUI inject the node's faults")
    args = parser.parse_args(argv)
    loaded = load_config(args.config)
    directory = Path(args.dir)
    service = loaded.config.service.model_copy(update={
        "socket_path": str(directory / "mill.sock"), "records_dir": str(directory / "records"), "tcp_port": 0,
    })
    bus = loaded.config.bus
    if bus.interface != "virtual":
        raise SystemExit(f"--sim runs the simulated node on the virtual bus; {args.config} uses {bus.interface}")
    loaded = dataclasses.replace(loaded, config=loaded.config.model_copy(update={"service": service}))
    threading.Thread(target=_stop_when_orphaned, args=(os.getppid(),), name="orphan-watch", daemon=True).start()
    return serve(loaded, fault_injection=args.fault_injection)


def _stop_when_orphaned(parent_pid: int) -> None:
    """SIGTERM ourselves (a controlled stop) if the TUI that started us dies without stopping us."""
    while os.getppid() == parent_pid:
        time.sleep(ORPHAN_CHECK_S)
    os.kill(os.getpid(), signal.SIGTERM)


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = ["START_TIMEOUT_S", "STOP_TIMEOUT_S", "SimService", "main"]

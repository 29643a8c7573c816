"""``millctl serve``: run the controller service (control loop, local API, records) until SIGTERM or Ctrl+C."""

from __future__ import annotations

import argparse
import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING

from millctl.cli.output import stderr_console

if TYPE_CHECKING:
    from millctl.api import ServiceOut
    from millctl.config.loader import LoadedConfig


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``serve``."""
    parser = subparsers.add_parser(
        "serve",
        help="run the controller service: the control loop, its API on a Unix socket, and the records",
        description=(
            "Run the controller on the configured bus (with the embedded simulated node on the 'virtual' bus), "
            "serve the local API on a Unix socket (service.socket_path, mode service.socket_mode; by default "
            "$XDG_RUNTIME_DIR/millctl/[INSTANCE/]millctl.sock, or /run/millctl under systemd), and record every "
            "event to <records_dir>/events.jsonl and every frame to <records_dir>/bus/ (by default "
            "$XDG_STATE_HOME/millctl/[INSTANCE/]records, or /var/lib/millctl/records under systemd; INSTANCE: one "
            "per config file, docs/deployment.md). SIGTERM or Ctrl+C "
            "stops the mill in a controlled way and exits 0. A second serve on the same socket exits 3. "
            "See docs/deployment.md."
        ),
    )
    parser.add_argument("--socket", metavar="PATH", help="Unix socket to serve on (default: service.socket_path)")
    parser.add_argument(
        "--sim", action="store_true",
        help="serve a simulated mill (virtual bus, embedded node) whatever bus the config names; "
             "its records go to <records_dir>-sim",
    )
    parser.add_argument(
        "--fault-injection", action="store_true",
        help="operator drills: let an instructor inject the simulated node's faults (TUI key f, POST "
             "/v1/sim/faults); refused (exit 2) unless the node is the embedded simulation (--sim or the "
             "virtual bus). See docs/operations.md#fault-drills",
    )
    parser.set_defaults(handler=_serve)


def simulated(loaded: LoadedConfig) -> LoadedConfig:
    """The configuration with a private virtual bus and the embedded node; records beside the real ones (-sim)."""
    from millctl.config.models import Bus
    from millctl.config.paths import service_paths

    config = loaded.config
    records = service_paths(loaded).records_dir
    drives = config.drives
    if drives.furnace_bus is not None:  # the furnace node's channel too (CiA 402 drives with a furnace)
        drives = drives.model_copy(update={"furnace_bus": Bus(interface="virtual",
                                                              channel=f"millctl-sim-furnace-{os.getpid()}")})
    sim = config.model_copy(update={
        "drives": drives,
        "bus": Bus(interface="virtual", channel=f"millctl-sim-{os.getpid()}"),
        "service": config.service.model_copy(update={"records_dir": f"{records}-sim", "tcp_port": 0}),
    })
    return dataclasses.replace(loaded, config=sim, source=f"{loaded.source} (--sim)")


def _serve(args: argparse.Namespace) -> int:
    from millctl.client import describe_mill
    from millctl.config import load_config
    from millctl.service import serve
    from millctl.service.host import realtime_policy_problem
    from millctl.service.sdnotify import Notifier

    loaded = load_config(args.config)
    if args.sim:
        loaded = simulated(loaded)
    console = stderr_console()
    service = loaded.config.service

    def ready(path: Path, described: ServiceOut) -> None:
        problem = realtime_policy_problem()
        if problem is not None:
            console.print(f"millctl serve: warning: {problem}", markup=False, highlight=False)
        Notifier().ready(f"serving {path}")  # systemd's Type=notify: started (no-op outside systemd)
        tcp = f", TCP 127.0.0.1:{service.tcp_port} (token)" if service.tcp_port else ""
        drill = "; FAULT INJECTION on (operator drills)" if described.fault_injection else ""
        console.print(
            f"millctl serve: {describe_mill(described)}{tcp}, records {described.records_dir}{drill}; "
            "Ctrl+C stops the mill and exits",
            markup=False, highlight=False,
        )

    code = serve(loaded, args.socket, on_ready=ready, fault_injection=args.fault_injection)
    console.print(f"millctl serve: stopped (exit {code})", markup=False)
    if args.json:  # one document, when the service has stopped: how it ended
        from millctl.cli.failures import EXIT_NAMES
        from millctl.cli.output import print_json
        from millctl.errors import ExitCode

        error = None if code == ExitCode.OK else {"code": EXIT_NAMES.get(ExitCode(code), "error"), "exit_code": code,
                                                  "message": f"millctl serve stopped with exit {code}"}
        print_json(args, {"exit_code": code, "config": loaded.source}, error)
    return code


__all__ = ["register", "simulated"]

"""``millctl serve``: run the controller service (control loop, local API, records) until SIGTERM or Ctrl+C."""

from __future__ import annotations

import argparse
from pathlib import Path

from millctl.cli.output import stderr_console


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``serve``."""
    parser = subparsers.add_parser(
        "serve",
        help="run the controller service: the control loop, its API on a Unix socket, and the records",
        description=(
            "Run the controller on the configured bus (with the embedded simulated node on the 'virtual' bus), "
            "serve the local API on a Unix socket (service.socket_path, mode service.socket_mode), and record "
            "every event to <records_dir>/events.jsonl and every frame to <records_dir>/bus/. SIGTERM or Ctrl+C "
            "stops the mill in a controlled way and exits 0. A second serve on the same socket exits 3."
        ),
    )
    parser.add_argument("--socket", metavar="PATH", help="Unix socket to serve on (default: service.socket_path)")
    parser.set_defaults(handler=_serve)


def _serve(args: argparse.Namespace) -> int:
    from millctl.config import load_config
    from millctl.service import serve

    loaded = load_config(args.config)
    console = stderr_console()
    service = loaded.config.service

    def ready(path: Path) -> None:
        tcp = f", TCP 127.0.0.1:{service.tcp_port} (token)" if service.tcp_port else ""
        console.print(
            f"millctl serve: {loaded.config.bus.interface}:{loaded.config.bus.channel}, socket {path}{tcp}, "
            f"records {service.records_dir}; Ctrl+C stops the mill and exits",
            markup=False,
        )

    code = serve(loaded, args.socket, on_ready=ready)
    console.print(f"millctl serve: stopped (exit {code})", markup=False)
    return code


__all__ = ["register"]

"""``millctl tui``: the operator terminal UI; ``--sim`` brings its own simulated service and node."""

from __future__ import annotations

import argparse
import importlib
import signal

from millctl.cli.output import stderr_console
from millctl.errors import ExitCode, InvalidInputError


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``tui``."""
    parser = subparsers.add_parser(
        "tui",
        help="the operator terminal UI: watch and command the mill through the running service",
        description=(
            "A full-screen terminal UI on the controller service: drives, furnace, envelope with the operating "
            "point, physics, link health, recipe and events; commands from the footer keys and the command palette "
            "(Ctrl+P); E-stop is Ctrl+X everywhere. Quitting never stops the service. With --sim a private "
            "simulated service and node are started for a demo, and stopped (controlled stop) on exit."
        ),
    )
    parser.add_argument("--socket", metavar="PATH", help="service socket (default: service.socket_path of the config)")
    parser.add_argument("--sim", action="store_true",
                        help="start the embedded default service with its simulated node on a private socket")
    parser.add_argument("--fault-injection", action="store_true",
                        help="with --sim: the instructor may inject the simulated node's faults (key f) for "
                             "operator drills; a running service gets this from `millctl serve --fault-injection`")
    parser.add_argument("--web", action="store_true",
                        help="serve the TUI to a browser on 127.0.0.1 only (textual-serve), each page read-only "
                             "until it takes control (c); from elsewhere through an SSH tunnel")
    parser.add_argument("--web-port", type=int, default=None, metavar="PORT",
                        help="with --web: the loopback port (default 8566; 0 picks a free one)")
    parser.set_defaults(handler=_tui)


class NoJsonForm(InvalidInputError):
    """``--json`` on an interactive command: refused (exit 1) as one JSON document, naming what gives the data."""

    def __init__(self, command: str) -> None:
        super().__init__(
            f"millctl {command} is interactive and has no JSON form: the mill's state as JSON is `millctl status "
            "--json`, its events the service's stream GET /v1/events (docs/operations.md#the-event-stream)"
        )


def _tui(args: argparse.Namespace) -> int:
    from millctl.tui import MillApp, SimService

    if args.json:
        raise NoJsonForm("tui")
    if args.web_port is not None and not args.web:
        stderr_console().print("millctl tui: --web-port goes with --web", markup=False)
        return int(ExitCode.INVALID_INPUT)
    if args.web and not args.sim:
        if args.fault_injection:
            raise InvalidInputError("millctl tui: --fault-injection goes with --sim")
        return _web(args, args.socket, sim=False)
    if not args.sim:
        if args.fault_injection:
            console = stderr_console()
            console.print("millctl tui: --fault-injection goes with --sim; a running service is started with "
                          "`millctl serve --fault-injection`", markup=False)
            return int(ExitCode.INVALID_INPUT)
        MillApp(args.socket, config=args.config).run()
        return int(ExitCode.OK)
    console = stderr_console()
    if args.socket:
        console.print("millctl tui: --sim uses its own private socket; drop --socket", markup=False)
        return int(ExitCode.INVALID_INPUT)
    console.print("millctl tui: starting the simulated service and node…", markup=False)
    with SimService(args.config, fault_injection=args.fault_injection) as sim:
        if args.web:
            return _web(args, sim.socket_path, sim=True)
        app = MillApp(sim.socket_path, sim=True)
        previous = signal.signal(signal.SIGHUP, lambda signum, frame: app.exit())  # terminal gone: leave, stop sim
        try:
            app.run()
        finally:
            signal.signal(signal.SIGHUP, previous)
        console.print("millctl tui: stopping the simulated service (controlled stop)…", markup=False)
    return int(ExitCode.OK)


def _web(args: argparse.Namespace, socket_path: str | None, *, sim: bool) -> int:
    """Serve the TUI to browsers on loopback until Ctrl+C (docs/operations.md#the-tui-in-a-browser)."""
    try:
        web = importlib.import_module("millctl.tui.web")  # imports textual-serve, an optional dependency
    except ImportError as exc:
        raise InvalidInputError(
            f"millctl tui --web needs textual-serve, which is not installed here ({exc}): "
            "pip install 'millctl[web]' (docs/deployment.md#6-clients)"
        ) from exc
    from millctl.client import Client

    sock = web.bind_loopback(web.DEFAULT_WEB_PORT if args.web_port is None else args.web_port)
    try:
        with Client(socket_path, config=args.config, name="tui-web") as client:
            service = client.service()  # no service: ServiceUnavailable, exit 3, before anyone opens the page
            where = client.socket_path or client.base_url
        command = web.session_command(where, None if sim else args.config, sim=sim)
        server = web.LoopbackServer(command, sock, title=f"millctl tui — {service.mill_name or where}",
                                    sim=sim)
    except BaseException:
        sock.close()
        raise
    server.serve()
    return int(ExitCode.OK)


__all__ = ["NoJsonForm", "register"]

"""``millctl status|set|arm|disarm|stop|estop|reset|watch``: talk to the running service through its API.

One-shot commands take control for their duration and give it back; when
another client holds it they exit 2 naming the holder. E-stop and stop need
no control: any client may stop the mill at any time (SAFETY 24). Data goes
to stdout (``--json`` for scripts), diagnostics to stderr.
Every command names the mill it talks to (config name, bus, simulated or
real, socket): on stderr, in the status view, and as ``mill`` in JSON.
"""

from __future__ import annotations

import argparse
from collections import deque
from typing import TYPE_CHECKING, Any

from millctl.api import EventKind
from millctl.cli.args import finite_float, nonnegative_float
from millctl.cli.output import print_json, stderr_console, stdout_console
from millctl.errors import ExitCode

if TYPE_CHECKING:
    from millctl.api import CommandOut, ControlOut, EventOut, ServiceOut, StatusOut
    from millctl.client import Client

SIMPLE_COMMANDS = {
    "arm": "arm the node (from DISABLED)",
    "disarm": "disarm the node (from ARMED at standstill)",
    "stop": "controlled stop: both drives ramp down inside the envelope, heater off (needs no control)",
    "estop": "emergency stop (needs no control; always accepted)",
    "reset": "clear a latched trip (drives at standstill, fresh telemetry)",
}

NEEDS_NO_CONTROL = frozenset({"estop", "stop"})
"""Commands any client may send while another holds control: stopping is always safe (SAFETY 24)."""


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the client commands."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--socket", metavar="PATH", help="service socket (default: service.socket_path of the config)")
    common.add_argument("--json", action="store_true", help="machine-readable output on stdout")
    take = argparse.ArgumentParser(add_help=False)
    take.add_argument("--force", action="store_true", help="take over control whose holder's lease has expired")
    waits = argparse.ArgumentParser(add_help=False)
    waits.add_argument("--wait", type=nonnegative_float, nargs="?", const=-1.0, default=None, metavar="TIMEOUT_S",
                      help="wait until the command's goal is reached (arm: ARMED, disarm: DISABLED, stop: standstill, "
                      "set: both drives at their targets, reset: trip cleared); exit 2 if not within TIMEOUT_S "
                      "(default: arm/disarm 10 s, stop 120 s, reset 15 s, set its ramp + 30 s)")

    status = subparsers.add_parser("status", parents=[common], help="the mill's status, from the running service",
                                   description="The controller's status and who holds control.")
    status.set_defaults(handler=_status)
    setp = subparsers.add_parser(
        "set", parents=[common, take, waits],
        help="ramp to new speeds (and furnace target); refused outside the envelope",
    )
    setp.add_argument("--rot-rpm", type=finite_float, required=True, help="rotary speed ω_r (rpm)")
    setp.add_argument("--vib-rpm", type=finite_float, required=True, help="vibration speed ω_v (rpm)")
    setp.add_argument("--temp-c", type=finite_float, help="furnace target (°C); refused together with the speeds")
    setp.add_argument("--heat-rate", type=finite_float, metavar="C_PER_MIN",
                      help="heating rate to --temp-c (°C/min; default: the furnace's maximum); needs --temp-c")
    setp.add_argument("--rot-rate", type=finite_float, help="rotary ramp rate (rpm/s; default: the drive's maximum)")
    setp.add_argument("--vib-rate", type=finite_float, help="vibration ramp rate (rpm/s; default: the drive's maximum)")
    setp.add_argument("--linear", action="store_true", help="one straight ramp in both axes (if inside the envelope)")
    setp.set_defaults(handler=_set)
    for name, text in SIMPLE_COMMANDS.items():
        if name == "estop":
            parents = [common]
        else:
            parents = [common, waits] if name in NEEDS_NO_CONTROL else [common, take, waits]
        sub = subparsers.add_parser(name, parents=parents, help=text)
        sub.set_defaults(handler=_simple, action=name)
    watch = subparsers.add_parser("watch", help="a live view of the mill (Ctrl+C to quit)",
                                  description="A live view of the mill from the service's event stream; "
                                  "Ctrl+C quits (exit 0).")
    watch.add_argument("--socket", metavar="PATH", help="service socket (default: service.socket_path of the config)")
    watch.set_defaults(handler=_watch)


def _client(args: argparse.Namespace) -> Client:
    from millctl.client import Client

    return Client(args.socket, config=args.config, name="cli")


def say_mill(client: Client) -> ServiceOut:
    """Name the mill on stderr; return the service's description."""
    from millctl.client import describe_mill

    service = client.service()
    stderr_console().print(f"millctl: {describe_mill(service)}", markup=False, highlight=False)
    return service


def _status(args: argparse.Namespace) -> int:
    with _client(args) as client:
        service = client.service()
        status = client.status()
        control = client.control_state()
    if args.json:
        print_json(args, {"mill": service, "status": status, "control": control})
    else:
        stdout_console().print(render_status(status, control, service=service))
    return int(ExitCode.OK)


def _set(args: argparse.Namespace) -> int:
    results = []
    with _client(args) as client, client.control(force=args.force):
        say_mill(client)
        results.append(
            client.set_speeds(
                args.rot_rpm,
                args.vib_rpm,
                rotary_rate_rpm_s=args.rot_rate,
                vibration_rate_rpm_s=args.vib_rate,
                linear=args.linear,
                temp_c=args.temp_c,  # one request: the service checks speeds and furnace whole
                rate_c_per_min=args.heat_rate,
            )
        )
        results[-1] = _waited(args, client, "set", results[-1])
    _report(args, results)
    return int(ExitCode.OK)


def _simple(args: argparse.Namespace) -> int:
    with _client(args) as client:
        say_mill(client)
        if args.action in NEEDS_NO_CONTROL:
            result = getattr(client, args.action)()
        else:
            with client.control(force=args.force):
                result = getattr(client, args.action)()
        if args.action != "estop":
            result = _waited(args, client, args.action, result)
    _report(args, [result])
    return int(ExitCode.OK)


def _waited(args: argparse.Namespace, client: Client, command: str, result: CommandOut) -> CommandOut:
    """With --wait (and always for reset, which completes when the node confirms): the state once reached."""
    from millctl.cli.wait import DEFAULT_TIMEOUT_S, wait_for_goal

    if args.wait is None and command != "reset":
        return result
    timeout_s = DEFAULT_TIMEOUT_S[command] + (result.duration_s or 0.0) if args.wait in (None, -1.0) else args.wait
    err = stderr_console()
    status = wait_for_goal(client, command, timeout_s, lambda line: err.print(f"millctl: {line}", markup=False))
    return result.model_copy(update={"state": status.state})


def _report(args: argparse.Namespace, results: list[CommandOut]) -> None:
    """Each accepted command and the state after it; with --json the last state is the result's ``state``."""
    if args.json:
        print_json(args, {"state": results[-1].state, "commands": results})
        return
    out = stdout_console()
    for result in results:
        ramp = f" (ramp {result.duration_s:.1f} s)" if result.duration_s else ""
        out.print(f"accepted: {result.message}{ramp}; state {result.state}", markup=False)


def _num(value: Any, fmt: str = ".1f", unit: str = "") -> str:
    if value is None:
        return "—"
    return f"{value:{fmt}}{unit}"


def render_status(
    status: StatusOut, control: ControlOut | None = None, events: Any = (), service: ServiceOut | None = None
) -> Any:
    """A compact rich view: mill, warnings, state, setpoints vs measured, limit, furnace, physics, links, events."""
    from rich.table import Table
    from rich.text import Text

    from millctl.api import BusCondition
    from millctl.client import describe_bus_health, describe_mill

    table = Table.grid(padding=(0, 2))
    table.add_column(style="bold")
    table.add_column()
    if service is not None:
        table.add_row("mill", describe_mill(service))
        for warning in service.warnings:
            table.add_row("WARNING", Text(warning, style="bold red"))
    s = status
    state = s.state + (f" — {s.trip_cause}" if s.trip_cause else "")
    table.add_row("state", f"{state}   node {s.node_state or '—'} {' '.join(s.node_faults)}")
    if s.drives:  # drives with their own state machine (CiA 402): each one's power state, in its words
        table.add_row("drives", f"{s.drives_backend}: " + "; ".join(
            d.name + (f" (node {d.node_id})" if d.node_id is not None else "") + f" {d.state}"
            + (f" — {d.detail}" if d.detail else "") for d in s.drives))
    if control is not None:
        holder = control.holder or "nobody"
        table.add_row("control", holder + (" (lease expired)" if control.expired else ""))
    table.add_row(
        "ω_r rotary",
        f"set {_num(s.setpoint_rotary_rpm)} → {_num(s.target_rotary_rpm)}   "
        f"measured {_num(s.measured_rotary_rpm)} rpm   torque {_num(s.rotary_torque_nm, '.2f')} N·m",
    )
    table.add_row(
        "ω_v vibration",
        f"set {_num(s.setpoint_vibration_rpm)} → {_num(s.target_vibration_rpm)}   "
        f"measured {_num(s.measured_vibration_rpm)} rpm   ramp {_num(s.ramp_remaining_s)} s left",
    )
    every = "" if s.law_is_every_cycle else "  (not the every-cycle bound here)"
    table.add_row(
        "limit",
        f"ω_r ≤ {_num(s.limit_rotary_rpm)} rpm, margin {_num(s.margin_rpm)} rpm   "
        f"law {s.law}, margin {_num(s.margin, '.0%')}{every}",
    )
    table.add_row(
        "furnace",
        f"{_num(s.furnace_temp_c, '.1f', ' °C')}   target {_num(s.furnace_target_c, '.1f', ' °C')}   "
        f"heater {_num(s.heater_pct, '.0f', ' %')}",
    )
    table.add_row(
        "physics",
        f"detached {s.detached if s.detached is not None else '—'}   θ_d "
        f"{_num(s.theta_d_deg, '.1f', '°')}   impacts {_num(s.impact_rate_hz, '.1f', ' Hz')}   "
        f"{_num(s.impact_energy_mj, '.2f', ' mJ')}   shear {_num(s.shear_kpa, '.1f', ' kPa')}",
    )
    links = [f"{name} {_num(link.age_s, '.2f', ' s')}{' STALE' if link.stale else ''}" for name, link in s.link.items()]
    table.add_row("links", "   ".join(links))
    healthy = s.bus_health.condition is BusCondition.ERROR_ACTIVE
    table.add_row("CAN bus", Text(describe_bus_health(s.bus_health), style="" if healthy else "bold red"))
    for event in events:
        table.add_row(f"#{event.seq}", f"[{event.kind}] {event.source}: {event.message}")
    return table


def _watch(args: argparse.Namespace) -> int:
    from rich.live import Live

    from millctl.cli.tui_cmd import NoJsonForm

    if args.json:
        raise NoJsonForm("watch")

    from millctl.api import EventOut

    console = stderr_console()
    events: deque[EventOut] = deque(maxlen=6)
    with _client(args) as client:
        service = client.service()
        control = client.control_state()
        status = client.status()
        try:
            first = render_status(status, control, service=service)
            with Live(first, console=console, refresh_per_second=4) as live:
                for item in client.stream():
                    if isinstance(item, EventOut):
                        events.append(item)
                        if item.kind is EventKind.CONTROL:
                            control = client.control_state()
                        elif item.kind is EventKind.RECORDS:
                            service = client.service()
                    else:
                        status = item
                    live.update(render_status(status, control, events, service=service))
        except KeyboardInterrupt:
            return int(ExitCode.OK)
    console.print("millctl watch: the service closed the stream", markup=False)
    return int(ExitCode.OK)


__all__ = ["register", "render_status", "say_mill"]

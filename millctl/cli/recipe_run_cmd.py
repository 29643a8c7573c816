"""``millctl recipe run|pause|resume|abort|status``: run recipes in the controller service.

``recipe run`` pre-flights the recipe, connects to the service, starts the run,
and follows it with a progress display on stderr and a summary on stdout; it
names the mill it talks to first. When no service runs it starts one with the
simulated node in a process of its own only if the configuration's bus is the
simulated one (``virtual``) or ``--sim`` asks for it: against a real-bus
configuration it says so and exits 3, so it never reports a run done on a
simulation while the real mill stood still. The run lives in the service, so closing the
terminal does not stop it. Ctrl+C once pauses the run now; twice aborts it
with a controlled stop. A trip or an abort ends with exit code 2.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from millctl.api import ControllerState, RunState
from millctl.cli.output import hms, print_json, stderr_console, stdout_console
from millctl.cli.recipe_resume_cmd import register_resume
from millctl.errors import BusError, ExitCode

if TYPE_CHECKING:
    from millctl.api import RecipeProgress, StatusOut
    from millctl.client import Client

POLL_S = 0.5
"""How often the progress display asks the service (s)."""
SERVICE_START_TIMEOUT_S = 60.0
LEASE_RENEW_S = 10.0


def register_run(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``recipe run``, ``pause``, ``resume``, ``abort`` and ``status``."""
    socket_opt = argparse.ArgumentParser(add_help=False)
    socket_opt.add_argument("--socket", metavar="PATH", help="service socket (default: service.socket_path)")
    run = sub.add_parser(
        "run", parents=[socket_opt], help="run a recipe in the service (starts the embedded one if needed)"
    )
    run.add_argument("file", help="the recipe (TOML)")
    run.add_argument("--json", action="store_true", help="print the summary as JSON")
    run.add_argument("--detach", action="store_true", help="start the run and return; follow it with `recipe status`")
    run.add_argument("--sim", action="store_true",
                     help="with no service running, start a simulated mill even if the config names a real bus")
    run.set_defaults(handler=_run)
    pause = sub.add_parser("pause", parents=[socket_opt], help="pause the running recipe at the next step boundary")
    pause.add_argument("--now", action="store_true", help="pause now, holding the current setpoints")
    pause.set_defaults(handler=_action, action="pause")
    register_resume(sub, socket_opt, _action)
    status = sub.add_parser("status", parents=[socket_opt], help="progress of the current or last run")
    status.add_argument("--json", action="store_true", help="machine-readable output")
    status.set_defaults(handler=_status)


def _client(args: argparse.Namespace, name: str = "recipe") -> Client:
    from millctl.client import Client

    return Client(args.socket, config=args.config, name=name)


def _action(args: argparse.Namespace) -> int:
    from millctl.cli.client_cmd import say_mill

    with _client(args) as client, client.control():
        say_mill(client)
        if args.action == "pause":
            progress = client.recipe_pause(now=args.now)
        elif args.action == "resume":
            progress = client.recipe_resume()
        else:
            progress = client.recipe_abort()
    if getattr(args, "json", False):
        print_json(args, progress)
        return int(ExitCode.OK)
    stdout_console().print(_line(progress.progress), markup=False)
    return int(ExitCode.OK)


def _status(args: argparse.Namespace) -> int:
    from millctl.cli.client_cmd import say_mill

    with _client(args) as client:
        say_mill(client)
        result = client.recipe()
    if args.json:
        print_json(args, result)
    else:
        progress = result.progress
        stdout_console().print(_line(progress) if progress else "no recipe has run in this service", markup=False)
    return int(ExitCode.OK)


class _EmbeddedService:
    """A ``millctl serve`` process started for this run, in its own session (Ctrl+C reaches only us)."""

    def __init__(self, args: argparse.Namespace, socket_path: str, *, sim: bool) -> None:
        from millctl.config.paths import ensure_private_dir

        command = [sys.executable, "-m", "millctl"]
        if args.config:
            command += ["--config", args.config]
        command += ["serve", "--socket", socket_path] + (["--sim"] if sim else [])
        self.socket_path = socket_path
        log_dir = Path(socket_path).parent
        ensure_private_dir(log_dir)  # 0750 as the service makes it, not the umask's 0755 (issue 39, item 6)
        self.log_path = log_dir / "embedded-service.log"
        self._log = open(self.log_path, "ab")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen(
            command, stdin=subprocess.DEVNULL, stdout=self._log, stderr=self._log, start_new_session=True
        )

    def wait_ready(self, client: Client) -> None:
        deadline = time.monotonic() + SERVICE_START_TIMEOUT_S
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise BusError(f"the embedded service exited with code {self.proc.returncode}; see {self.log_path}")
            with contextlib.suppress(BusError):
                if client.status().state is not ControllerState.DISCONNECTED:  # the controller has seen the node
                    return
            time.sleep(0.2)
        raise BusError(
            f"the embedded service did not start within {SERVICE_START_TIMEOUT_S:.0f} s; see {self.log_path}"
        )

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=60.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._log.close()


def _run(args: argparse.Namespace) -> int:
    from millctl.cli.recipe_cmd import preflight
    from millctl.client import Client, ServiceUnavailable, describe_mill

    loaded, plan = preflight(args)  # every violation, before anything moves
    client = Client(args.socket, config=args.config, name="recipe")
    embedded: _EmbeddedService | None = None
    err = stderr_console()
    try:
        try:
            client.status()
        except ServiceUnavailable:
            assert client.socket_path is not None
            embedded = _start_simulation(args, client.socket_path, err)
            if embedded.socket_path != client.socket_path:
                client.close()
                client = Client(embedded.socket_path, name="recipe")
            embedded.wait_ready(client)
        err.print(f"millctl: {describe_mill(client.service())}", markup=False, highlight=False)
        client.take_control()
        started = client.recipe_run(os.path.abspath(loaded.source)).progress
        assert started is not None  # the service answers a started run with its progress
        err.print(
            f"run {started.run_id}: {loaded.recipe.recipe.name} ({len(plan.steps)} steps, "
            f"{plan.total_s:.0f} s planned) — Ctrl+C pauses, twice aborts"
        )
        if args.detach and args.json:
            print_json(args, {"run_id": started.run_id, "progress": started})
            return int(ExitCode.OK)
        if args.detach:
            stdout_console().print(
                f"run {started.run_id} started; follow with `millctl recipe status`", markup=False
            )
            return int(ExitCode.OK)
        final = follow(client)
    finally:
        with contextlib.suppress(BusError, Exception):
            client.release_control()
        client.close()
        if embedded is not None:
            embedded.stop()
    return summary(args, final)


def _start_simulation(args: argparse.Namespace, socket_path: str, err: Any) -> _EmbeddedService:
    """Start a simulated mill for this run, only if the config's bus is the simulated one or ``--sim`` asks."""
    from millctl.config import load_config

    bus = load_config(args.config).config.bus
    real = bus.interface != "virtual"
    if real and not args.sim:
        raise BusError(
            f"no service on {socket_path}, and the configuration names a real bus ({bus.interface}:"
            f"{bus.channel}): not starting a simulated mill in its place. Start the service (`millctl serve`, or "
            "its systemd unit: docs/deployment.md), pass --socket, or --sim for a simulation"
        )
    if real:  # --sim against a real-bus config: the simulation gets a socket of its own, never the real mill's
        from millctl.config.paths import runtime_dir

        socket_path = str(runtime_dir() / f"millctl-sim-{os.getpid()}.sock")
    err.print(f"no service on {socket_path}: starting a SIMULATED mill (embedded service and simulated node)",
              markup=False)
    return _EmbeddedService(args, socket_path, sim=real)


class _Interrupts:
    """Counts Ctrl+C presses with a signal handler, so that none is lost while a request is in flight."""

    def __init__(self) -> None:
        self.count = 0

    def __enter__(self) -> _Interrupts:
        self._previous = signal.signal(signal.SIGINT, self._on_sigint)
        return self

    def __exit__(self, *exc: object) -> None:
        signal.signal(signal.SIGINT, self._previous)

    def _on_sigint(self, signum: int, frame: object) -> None:
        self.count += 1


def follow(client: Client) -> RecipeProgress:
    """Show progress until the run ends; Ctrl+C once pauses now, twice aborts."""
    from rich.live import Live

    from millctl.client import ServiceRefused

    acted = 0
    last_renew = time.monotonic()
    clock = _StopClock()
    console = stderr_console()
    display = Live(console=console, refresh_per_second=4) if console.is_terminal else _PlainLines(console)
    with _Interrupts() as interrupts, display as live:
        while True:
            if interrupts.count > acted:
                acted = interrupts.count
                try:
                    if acted == 1:
                        client.recipe_pause(now=True)
                        live.console.print("[yellow]paused[/] — `millctl recipe resume` continues; Ctrl+C again aborts")
                    elif acted == 2:
                        client.recipe_abort()
                        live.console.print("[red]aborting[/]: controlled stop")
                except ServiceRefused as refused:  # e.g. already paused by a pause step, or already stopping
                    live.console.print(f"[yellow]{refused}[/]")
            progress = client.recipe().progress
            if progress is None:
                raise BusError("the service has no recipe run: was it restarted?")
            if isinstance(live, _PlainLines):
                live.show(progress, client.status(), clock.remaining_s(progress))
            else:
                live.update(_panel(progress, client.status(), clock.remaining_s(progress)))
            if progress.state.final or progress.state is RunState.INTERRUPTED:
                return progress
            if time.monotonic() - last_renew > LEASE_RENEW_S:
                client.take_control()
                last_renew = time.monotonic()
            time.sleep(POLL_S)


PLAIN_EVERY_S = 2.0
"""With stderr not a terminal (a pipe, a log file): a plain progress line this often (s), and at every change."""


class _PlainLines:
    """Progress as plain lines, for a stderr that is no terminal (a live display would show nothing there)."""

    def __init__(self, console: Any) -> None:
        self.console = console
        self._last: tuple[object, ...] | None = None
        self._said = 0.0

    def __enter__(self) -> _PlainLines:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def show(self, progress: RecipeProgress, status: StatusOut, remaining_s: float | None) -> None:
        """Print a line when the step or state changed, or :data:`PLAIN_EVERY_S` after the last one."""
        now = time.monotonic()
        key = (progress.state, progress.step, progress.kind, progress.reason)
        if key == self._last and now - self._said < PLAIN_EVERY_S:
            return
        self._last, self._said = key, now
        self.console.print(
            f"{progress.recipe}: {progress.state} {_step(progress)}, elapsed {hms(progress.elapsed_s or 0.0)}, "
            f"remaining {_hms(remaining_s)}; ω_r {_num(status.measured_rotary_rpm)} rpm, ω_v "
            f"{_num(status.measured_vibration_rpm)} rpm, furnace {_num(status.furnace_temp_c)} °C"
            + (f" — {progress.reason}" if progress.reason else ""),
            markup=False, highlight=False,
        )


class _StopClock:
    """Counts the final stop down: the service reports its planned duration while STOPPING, not the time left."""

    def __init__(self) -> None:
        self.since: float | None = None

    def remaining_s(self, progress: RecipeProgress) -> float | None:
        """Time left (s): the service's, or while STOPPING its stop duration minus the time spent stopping."""
        if progress.state is not RunState.STOPPING:
            self.since = None
            return progress.remaining_s
        now = time.monotonic()
        if self.since is None:
            self.since = now
        return None if progress.remaining_s is None else max(progress.remaining_s - (now - self.since), 0.0)


def _panel(progress: RecipeProgress, status: StatusOut, remaining_s: float | None) -> Any:
    from rich.progress_bar import ProgressBar
    from rich.table import Table

    elapsed = progress.elapsed_s or 0.0
    total = elapsed + (remaining_s or 0.0)
    grid = Table.grid(padding=(0, 2))
    grid.add_row("run", f"{progress.recipe}  {progress.state}" + (f" — {progress.reason}" if progress.reason else ""))
    grid.add_row("", ProgressBar(total=max(total, 1e-9), completed=elapsed, width=40))
    grid.add_row("", f"{_step(progress)}   elapsed {hms(elapsed)}   remaining {_hms(remaining_s)}")
    s = status
    grid.add_row(
        "speeds",
        f"ω_r {_num(s.setpoint_rotary_rpm)} rpm (measured {_num(s.measured_rotary_rpm)}), "
        f"limit {_num(s.limit_rotary_rpm)} rpm; ω_v {_num(s.setpoint_vibration_rpm)} rpm "
        f"(measured {_num(s.measured_vibration_rpm)})",
    )
    grid.add_row("furnace", f"{_num(s.furnace_temp_c)} °C (setpoint {_num(s.furnace_setpoint_c)})")
    grid.add_row("state", f"{s.state} {s.trip_cause}")
    return grid


def _num(value: float | None) -> str:
    return "—" if value is None else f"{value:.1f}"


def _hms(seconds: float | None) -> str:
    return "—" if seconds is None else hms(seconds)


def _step(progress: RecipeProgress) -> str:
    """``step 2/4 (hold)``; after the last step, the final stop or the end, never ``(None)``."""
    if progress.kind is not None:
        return f"step {progress.step}/{progress.steps} ({progress.kind})"
    if progress.state is RunState.STOPPING:
        return f"steps {progress.steps}/{progress.steps} done, stopping"
    return f"step {progress.step}/{progress.steps}"


def _line(progress: RecipeProgress | None) -> str:
    if progress is None:
        return "no run"
    return (
        f"{progress.state} {_step(progress)}, elapsed {_hms(progress.elapsed_s)}, "
        f"remaining ≈ {_hms(progress.remaining_s)}" + (f" — {progress.reason}" if progress.reason else "")
    )


def summary(args: argparse.Namespace, final: RecipeProgress) -> int:
    """Print the run's end (text or --json); exit 0 for DONE, else 2."""
    ok = final.state is RunState.DONE
    if args.json:
        error = None if ok else {"code": f"run_{final.state.lower()}", "exit_code": int(ExitCode.INTERLOCK),
                                 "message": f"recipe run {final.run_id} {final.state}: {final.reason or ''}"}
        print_json(args, final, error)
    else:
        out = stdout_console()
        out.print(f"recipe {final.recipe}: {final.state}", markup=False)
        out.print(f"  run id   {final.run_id}", markup=False)
        out.print(f"  steps    {final.step}/{final.steps}", markup=False)
        out.print(f"  elapsed  {_hms(final.elapsed_s)}"
                  + (f" (and {hms(final.gap_s)} interrupted)" if final.gap_s else ""), markup=False)
        if final.reason:
            out.print(f"  reason   {final.reason}", markup=False)
        out.print(f"  record   {final.record}", markup=False)
        out.print(f"  report   millctl report {final.record}", markup=False)
    return int(ExitCode.OK) if ok else int(ExitCode.INTERLOCK)

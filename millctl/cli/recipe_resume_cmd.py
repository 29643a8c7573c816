"""``millctl recipe list|resume [RUN]|abort [RUN]``: find, resume or close the runs a service stop or crash interrupted.

``recipe resume`` alone continues a paused or held run of the running
service. ``recipe resume RUN`` continues a run the service stopped or died
under (docs/operations.md#resume): it shows the run (step, time done, gap)
and the service's pre-flight from the mill's state now (drives standing
still, node ready, the ramp back to the step's setpoints from the measured
values inside the envelope), asks the operator (``--yes`` answers for a
script), then follows the run like ``recipe run``. ``recipe abort RUN``
closes an interrupted run for good; ``recipe list`` shows them.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from millctl.api import RunState
from millctl.cli.output import hms, print_json, stderr_console, stdout_console
from millctl.errors import ExitCode, InterlockError

if TYPE_CHECKING:
    from millctl.api import RecipeResumeOut, UnfinishedRunOut
    from millctl.client import Client


class NotConfirmed(InterlockError):
    """The operator did not confirm a resume (exit 2: refused, nothing moved)."""


def register_resume(sub: argparse._SubParsersAction[argparse.ArgumentParser], socket_opt: argparse.ArgumentParser,
                    action: Callable[[argparse.Namespace], int]) -> None:
    """Add ``recipe list``, ``recipe resume [RUN]`` and ``recipe abort [RUN]``; ``action`` runs them without RUN."""
    listing = sub.add_parser("list", parents=[socket_opt],
                             help="the unfinished runs a service stop, crash or reboot interrupted")
    listing.add_argument("--json", action="store_true", help="machine-readable output")
    listing.set_defaults(handler=_list)
    resume = sub.add_parser("resume", parents=[socket_opt],
                            help="resume a paused or held run; with RUN, an interrupted run (after a pre-flight)")
    resume.add_argument("run", nargs="?", metavar="RUN", help="the interrupted run's id (`millctl recipe list`)")
    resume.add_argument("--yes", action="store_true", help="confirm without asking (resuming moves the mill)")
    resume.add_argument("--recipe", metavar="FILE",
                        help="the recipe file, when the run record keeps no recipe text; it must be unchanged")
    resume.add_argument("--detach", action="store_true", help="resume and return; follow with `recipe status`")
    resume.add_argument("--json", action="store_true", help="print the summary as JSON")
    resume.set_defaults(handler=_resume, action="resume", fallback=action)
    abort = sub.add_parser("abort", parents=[socket_opt],
                           help="abort the run (controlled stop); with RUN, close an interrupted run for good")
    abort.add_argument("run", nargs="?", metavar="RUN", help="the interrupted run's id (`millctl recipe list`)")
    abort.set_defaults(handler=_abort, action="abort", fallback=action)


def _client(args: argparse.Namespace) -> Client:
    from millctl.client import Client

    return Client(args.socket, config=args.config, name="recipe")


def _when(unix: float) -> str:
    return time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(unix))


def describe_run(run: UnfinishedRunOut) -> list[str]:
    """An interrupted run in lines: recipe, step and its time done, the run's time, the gap and why."""
    step = (f"step {min(run.step, run.steps)}/{run.steps} ({run.kind})" if run.kind
            else f"before step {run.step}/{run.steps}" if run.step <= run.steps else "after its last step")
    gap = run.gaps[-1]
    return [
        f"run {run.run_id}: {run.recipe} ({run.recipe_file}), {run.state}",
        f"  at       {step}, {hms(run.step_elapsed_s)} of it done at its setpoints"
        + (f", {run.step_dose_kj_g:.4g} kJ/g" if run.step_dose_kj_g else ""),
        f"  ran      {hms(run.elapsed_s)} since {_when(run.started_unix)}",
        f"  stopped  {_when(gap.start_unix)} ({hms(time.time() - gap.start_unix)} ago): {gap.reason}",
        f"  record   {run.record}",
    ]


def _list(args: argparse.Namespace) -> int:
    from millctl.cli.client_cmd import say_mill

    with _client(args) as client:
        say_mill(client)
        runs = client.recipe_unfinished()
    if args.json:
        print_json(args, runs)
        return int(ExitCode.OK)
    out = stdout_console()
    if not runs.runs:
        out.print("no unfinished runs", markup=False)
    for run in runs.runs:
        for line in describe_run(run):
            out.print(line, markup=False, highlight=False)
        out.print(f"  resume   millctl recipe resume {run.run_id}   (close: millctl recipe abort {run.run_id})",
                  markup=False, highlight=False)
    return int(ExitCode.OK)


def _confirm(args: argparse.Namespace, preview: RecipeResumeOut) -> None:
    """The operator's yes: --yes, or an answer on the terminal; refuse (exit 2) otherwise."""
    if args.yes:
        return
    if not sys.stdin.isatty():
        raise NotConfirmed(f"resuming run {preview.run.run_id} moves the mill: confirm with --yes "
                           "(stdin is not a terminal to ask on)")
    err = stderr_console()
    err.print(f"Resume run {preview.run.run_id} now? The mill will move. [y/N] ", end="", markup=False)
    answer = sys.stdin.readline().strip().lower()
    if answer not in ("y", "yes"):
        raise NotConfirmed(f"run {preview.run.run_id} not resumed (answer {answer!r}); nothing moved")


def _resume(args: argparse.Namespace) -> int:
    if args.run is None:
        return int(args.fallback(args))
    from millctl.cli.client_cmd import say_mill
    from millctl.cli.recipe_run_cmd import follow, summary
    from millctl.client import read_recipe_text

    text = read_recipe_text(args.recipe)[1] if args.recipe else None
    err = stderr_console()
    with _client(args) as client, client.control():
        say_mill(client)
        current = client.recipe().progress
        if current is not None and current.run_id == args.run and current.state.resumable:
            resumed = client.recipe_resume().progress  # a paused or held run of this service
            stdout_console().print(f"run {args.run} resumed: {resumed.state if resumed else '?'}", markup=False)
            return int(ExitCode.OK)
        preview = client.recipe_resume_run(args.run, confirm=False, text=text)
        for line in describe_run(preview.run):
            err.print(line, markup=False, highlight=False)
        check = preview.check
        err.print(f"  now      controller {check.controller_state}, measured ω_r {_num(check.measured_rotary_rpm)} "
                  f"/ ω_v {_num(check.measured_vibration_rpm)} rpm, furnace {_num(check.furnace_temp_c)} °C",
                  markup=False, highlight=False)
        err.print(f"  plan     {check.restore}", markup=False, highlight=False)
        if not check.ok:
            raise InterlockError(f"run {args.run} cannot be resumed now:\n"
                                 + "\n".join(f"  {p}" for p in check.problems))
        _confirm(args, preview)
        started = client.recipe_resume_run(args.run, confirm=True, text=text)
        progress = started.recipe.progress if started.recipe else None
        err.print(f"run {args.run} resumed at step {progress.step if progress else '?'}; Ctrl+C pauses, twice aborts",
                  markup=False)
        if args.detach and args.json:
            print_json(args, {"run_id": args.run, "progress": progress})
            return int(ExitCode.OK)
        if args.detach:
            stdout_console().print(f"run {args.run} resumed; follow with `millctl recipe status`", markup=False)
            return int(ExitCode.OK)
        final = follow(client)
    return summary(args, final)


def _num(value: float | None) -> str:
    return "—" if value is None else f"{value:.1f}"


def _abort(args: argparse.Namespace) -> int:
    if args.run is None:
        return int(args.fallback(args))
    from millctl.cli.client_cmd import say_mill

    with _client(args) as client, client.control():
        say_mill(client)
        closed = client.recipe_close_run(args.run)
    if args.json:
        print_json(args, closed)
        return int(ExitCode.OK)
    stdout_console().print(f"run {closed.run_id} closed: {RunState.ABORTED} (its record ends; it can no longer be "
                           "resumed)", markup=False)
    return int(ExitCode.OK)


__all__ = ["NotConfirmed", "describe_run", "register_resume"]

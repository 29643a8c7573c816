"""Milling plans for the bluesky RunEngine: mill at a point, ramp through points, mill and measure, run a recipe.

Every plan is checked up front by the service's own pre-flight (``POST /v1/recipe/check``, what ``millctl recipe
check`` runs): a plan whose trajectory would leave the envelope fails with :class:`PreflightRefused` before the
first move. Each plan stages the mill (takes the control lease) and the detectors, opens one run whose start
document names the mill, its configuration's sha256, the law and margin and, for a recipe, the run record's id
(``millctl_run_id``), and ends with the drives at rest. Readings go to the ``primary`` stream every ``period_s``;
measurements taken with the drives paused go to ``measurement``, a recipe's step boundaries to ``steps``.

Time at a point counts only between two readings that both found the mill there: a trip, a suspension or a
ramp back after one does not count towards a hold.
"""

from __future__ import annotations

import os
import time
from collections.abc import Awaitable, Callable, Generator, Sequence
from pathlib import Path
from typing import Any, TypeVar

import bluesky.plan_stubs as bps
import bluesky.preprocessors as bpp
from bluesky.protocols import Readable
from bluesky.utils import Msg

from millctl.api import RecipeCheckOut, RecipeProgress, RunState
from millctl.bluesky.devices import Mill, MillPoint
from millctl.bluesky.recipe_text import Hold, Ramp, Step, recipe_toml
from millctl.client import read_recipe_text
from millctl.errors import InterlockError

T = TypeVar("T")
Plan = Generator[Msg, Any, T]
REST = MillPoint(0.0, 0.0)


class PreflightRefused(InterlockError):
    """The service's pre-flight refused the plan's trajectory (or its recipe is invalid): nothing was moved."""

    def __init__(self, name: str, check: RecipeCheckOut) -> None:
        self.check = check
        super().__init__(f"plan {name} refused by the service's pre-flight under {check.law}, before any move: "
                         + "; ".join(check.problems))


class RecipeFailed(InterlockError):
    """A recipe run as a plan ended FAILED or ABORTED (as ``millctl recipe run`` exits 2)."""

    def __init__(self, progress: RecipeProgress) -> None:
        self.progress = progress
        super().__init__(f"recipe run {progress.run_id} ({progress.recipe}) ended {progress.state}: "
                         f"{progress.reason or 'no reason given'}; record {progress.record}")


def call(fn: Callable[[], Awaitable[T]]) -> Plan[T]:
    """Await ``fn()`` in the RunEngine's loop and return its result (its exception is raised in the plan)."""
    (task,) = yield from bps.wait_for([fn])
    result: T = task.result()
    return result


def preflight(mill: Mill, name: str, text: str) -> Plan[RecipeCheckOut]:
    """The service's pre-flight of the recipe ``text``; raises :class:`PreflightRefused` with every problem."""
    client = mill.require_link().client
    check = yield from call(lambda: client.recipe_check_text(name, text))
    if not check.ok:
        raise PreflightRefused(name, check)
    return check


def _metadata(mill: Mill, plan_name: str, args: dict[str, Any], md: dict[str, Any] | None) -> Plan[dict[str, Any]]:
    client = mill.require_link().client
    events = yield from call(lambda: client.events(after=2**62, limit=1))
    service = mill.service
    assert service is not None
    return {"plan_name": plan_name, "plan_args": args, "millctl_mill": service.mill_name,
            "millctl_config_sha256": service.config_sha256, "millctl_law": service.law,
            "millctl_margin": service.margin, "millctl_simulated": service.simulated,
            "millctl_events_after": events.last_seq, **(md or {})}


def hold_at(mill: Mill, point: MillPoint, seconds: float, detectors: Sequence[Readable[Any]] = (),
            period_s: float = 1.0) -> Plan[float]:
    """Keep the mill at ``point`` for ``seconds`` of verified time there, reading every ``period_s``; return it.

    A checkpoint comes before each move and after each reading, so a suspension replays the move it cut short,
    or only the wait; the next pass then finds the mill away from the point (it tripped and stopped) and moves it
    back before any more time counts.
    """
    done_s = 0.0
    last_s: float | None = None
    while done_s < seconds:
        if not mill.at_point(point.rotary_rpm, point.vibration_rpm):
            last_s = None
            yield from bps.checkpoint()
            yield from bps.mv(mill, point)
            continue
        yield from bps.trigger_and_read([mill, *detectors])
        now_s = time.monotonic()
        if last_s is not None:
            done_s += now_s - last_s
        last_s = now_s
        yield from bps.checkpoint()
        if done_s < seconds:
            yield from bps.sleep(min(period_s, seconds - done_s))
    return done_s


def _staged_run(mill: Mill, detectors: Sequence[Readable[Any]], md: dict[str, Any], body: Plan[Any]) -> Plan[Any]:
    devices = [mill, *detectors]
    return (yield from bpp.stage_wrapper(bpp.run_wrapper(body, md=md), devices))


def mill_at(mill: Mill, rotary_rpm: float, vibration_rpm: float, *, duration_s: float | None = None,
            dose_kj_g: float | None = None, temp_c: float | None = None, detectors: Sequence[Readable[Any]] = (),
            period_s: float = 1.0, md: dict[str, Any] | None = None) -> Plan[Any]:
    """Mill at ``rotary_rpm``/``vibration_rpm`` for ``duration_s`` seconds or to ``dose_kj_g`` kJ/g, then stop.

    A time is held by the plan (the mill's movables, suspendable); a dose is integrated by the service's recipe
    runner from the node's physics telemetry, so it runs as a two-step recipe (ramp, hold to the dose) with its
    run record, exactly as ``millctl recipe run`` would.
    """
    steps: list[Step] = [Ramp(rotary_rpm, vibration_rpm, temp_c), Hold(duration_s=duration_s, dose_kj_g=dose_kj_g)]
    name = f"mill_at {rotary_rpm:g}/{vibration_rpm:g} rpm"
    text = recipe_toml(name, steps)
    args = {"rotary_rpm": rotary_rpm, "vibration_rpm": vibration_rpm, "duration_s": duration_s,
            "dose_kj_g": dose_kj_g, "temp_c": temp_c, "period_s": period_s}
    if dose_kj_g is not None:
        return (yield from run_recipe_text(mill, name, text, detectors=detectors, period_s=period_s,
                                           md={"plan_name": "mill_at", "plan_args": args, **(md or {})}))
    assert duration_s is not None
    yield from preflight(mill, name, text)
    meta = yield from _metadata(mill, "mill_at", args, md)
    point = MillPoint(rotary_rpm, vibration_rpm, temp_c)

    def body() -> Plan[float]:
        done_s = yield from hold_at(mill, point, duration_s, detectors, period_s)
        yield from bps.mv(mill, REST)
        return done_s

    return (yield from _staged_run(mill, detectors, meta, body()))


def ramp_through(mill: Mill, points: Sequence[MillPoint | tuple[float, ...]], *, dwell_s: float,
                 detectors: Sequence[Readable[Any]] = (), period_s: float = 1.0,
                 md: dict[str, Any] | None = None) -> Plan[Any]:
    """Visit each point in turn, dwelling ``dwell_s`` at each; the whole path pre-flighted before the first move."""
    visits = [MillPoint(*p) for p in points]
    steps: list[Step] = []
    for p in visits:
        steps += [Ramp(p.rotary_rpm, p.vibration_rpm, p.temp_c), Hold(duration_s=dwell_s)]
    name = f"ramp_through {len(visits)} points"
    yield from preflight(mill, name, recipe_toml(name, steps))
    args = {"points": [list(p) for p in visits], "dwell_s": dwell_s, "period_s": period_s}
    meta = yield from _metadata(mill, "ramp_through", args, md)

    def body() -> Plan[None]:
        for p in visits:
            yield from hold_at(mill, p, dwell_s, detectors, period_s)
        yield from bps.mv(mill, REST)

    return (yield from _staged_run(mill, detectors, meta, body()))


def mill_and_measure(mill: Mill, rotary_rpm: float, vibration_rpm: float, *, mill_s: float, cycles: int,
                     detectors: Sequence[Readable[Any]], period_s: float = 1.0,
                     md: dict[str, Any] | None = None) -> Plan[Any]:
    """``cycles`` times: mill ``mill_s`` at the point, bring the drives to rest, measure with ``detectors``, go on.

    The measurements (the detectors and the mill, at rest) go to the ``measurement`` stream; the readings while
    milling to ``primary``.
    """
    if cycles < 1:
        raise ValueError(f"cycles = {cycles}: give at least one milling cycle")
    steps: list[Step] = []
    for _ in range(cycles):
        steps += [Ramp(rotary_rpm, vibration_rpm), Hold(duration_s=mill_s), Ramp(0.0, 0.0)]
    name = f"mill_and_measure {rotary_rpm:g}/{vibration_rpm:g} rpm × {cycles}"
    yield from preflight(mill, name, recipe_toml(name, steps))
    args = {"rotary_rpm": rotary_rpm, "vibration_rpm": vibration_rpm, "mill_s": mill_s, "cycles": cycles,
            "period_s": period_s}
    meta = yield from _metadata(mill, "mill_and_measure", args, md)
    point = MillPoint(rotary_rpm, vibration_rpm)

    def body() -> Plan[None]:
        for _ in range(cycles):
            yield from hold_at(mill, point, mill_s, (), period_s)
            yield from bps.mv(mill, REST)
            yield from bps.checkpoint()
            yield from bps.trigger_and_read([*detectors, mill], name="measurement")

    return (yield from _staged_run(mill, detectors, meta, body()))


def run_recipe(mill: Mill, path: str | os.PathLike[str], *, detectors: Sequence[Readable[Any]] = (),
               period_s: float = 1.0, md: dict[str, Any] | None = None) -> Plan[RecipeProgress]:
    """A TOML recipe file as a plan: run by the service's recipe runner, step for step, as ``millctl recipe run``."""
    name, text = read_recipe_text(Path(path))
    return (yield from run_recipe_text(mill, name, text, detectors=detectors, period_s=period_s, md=md))


def run_recipe_text(mill: Mill, name: str, text: str, *, detectors: Sequence[Readable[Any]] = (),
                    period_s: float = 1.0, md: dict[str, Any] | None = None) -> Plan[RecipeProgress]:
    """Pre-flight, start and follow a recipe given as TOML text; its run record's id is in the start document.

    The mill (and the detectors) are read every ``period_s`` (``primary``) and at every step's start (``steps``).
    A run that ends FAILED or ABORTED fails the plan (:class:`RecipeFailed`); a plan that ends otherwise while
    the run goes on (an error, the RunEngine's abort) aborts the run with a controlled stop.
    """
    yield from preflight(mill, name, text)
    client = mill.require_link().client
    meta = yield from _metadata(mill, "run_recipe", {"recipe": name}, None)
    final: list[RecipeProgress] = []

    def body() -> Plan[str]:
        out = yield from call(lambda: client.recipe_run_text(name, text))
        assert out.progress is not None
        mill.note_run(out.progress.run_id)
        run_md = {**meta, "millctl_run_id": out.progress.run_id, "millctl_run_record": out.progress.record,
                  **(md or {})}
        run_uid: str = yield from bpp.run_wrapper(_follow(mill, detectors, period_s, final), md=run_md)
        return run_uid

    def cleanup() -> Plan[None]:
        mill.note_run("")
        if not final:
            progress = (yield from call(client.recipe)).progress
            if progress is not None and not progress.state.final and progress.state is not RunState.INTERRUPTED:
                yield from call(client.recipe_abort)

    yield from bpp.stage_wrapper(bpp.finalize_wrapper(body(), cleanup()), [mill, *detectors])
    (progress,) = final
    if progress.state is not RunState.DONE:
        raise RecipeFailed(progress)
    return progress


def _follow(mill: Mill, detectors: Sequence[Readable[Any]], period_s: float,
            final: list[RecipeProgress]) -> Plan[RecipeProgress]:
    client = mill.require_link().client
    step: tuple[int, str | None] | None = None
    while True:
        progress = (yield from call(client.recipe)).progress
        assert progress is not None
        if (progress.step, progress.kind) != step and progress.kind is not None:
            step = (progress.step, progress.kind)
            yield from bps.trigger_and_read([mill, *detectors], name="steps")
        yield from bps.trigger_and_read([mill])
        if progress.state.final or progress.state is RunState.INTERRUPTED:
            final.append(progress)
            return progress
        yield from bps.sleep(period_s)


__all__ = ["PreflightRefused", "RecipeFailed", "call", "hold_at", "mill_and_measure", "mill_at", "preflight",
           "ramp_through", "run_recipe", "run_recipe_text"]

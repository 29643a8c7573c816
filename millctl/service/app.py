"""The service's HTTP API (FastAPI, ``/v1``): status, envelope, control lease, commands, events, stream, recipes.

Commands need the control lease (header ``X-Millctl-Lease``); E-stop and a
controlled STOP need nothing and are accepted from any client at any time
(SAFETY 24), on a path of their own that no other request can fill
(:meth:`ServiceRuntime.call_urgent`). Every request is validated and every error
is JSON (see :mod:`millctl.service.errors`). No route, field or flag turns
the interlock off (SAFETY 14): every command goes through the controller.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import AsyncIterator
from typing import Annotated, Any

from fastapi import Body, FastAPI, Header, Path, Query
from sse_starlette import EventSourceResponse, ServerSentEvent
from starlette.concurrency import run_in_threadpool

from millctl import __version__
from millctl.api import (
    CheckOut,
    CheckRequest,
    CommandOut,
    ControllerState,
    ControlOut,
    EnvelopeOut,
    ErrorBody,
    EventKind,
    EventsOut,
    FurnaceRequest,
    LeaseOut,
    RecipeCheckOut,
    RecipeOut,
    RecipePauseRequest,
    RecipeProgress,
    RecipeResumeOut,
    RecipeResumeRequest,
    RecipeRunRequest,
    RunState,
    ServiceOut,
    SetpointsRequest,
    StatusOut,
    StreamKind,
    TakeRequest,
    UnfinishedRunOut,
    UnfinishedRunsOut,
)
from millctl.controller import Controller
from millctl.recipes.history import RUN_ID_PATTERN, RunLock, repair_tail
from millctl.safety import InterlockRefused
from millctl.service.envelope_view import envelope_out
from millctl.service.errors import COMMAND_RESPONSES, READ_RESPONSES, install_error_handlers, refusal_list
from millctl.service.faults import add_fault_routes
from millctl.service.headers import ClientName, LeaseId, client_source
from millctl.service.journal import finite
from millctl.service.limits import BodyLimit
from millctl.service.recipe import unfinished_out
from millctl.service.runtime import ServiceRuntime

STATUS_PERIOD_S = 0.25
"""The stream sends a status this often (s)."""
STREAM_POLL_S = 0.05
"""The stream looks for new events this often (s)."""
SETTLE_S = 2.0
"""A command's answer waits at most this long for the state the command leads to (s), then reports the state as is."""
SETTLE_POLL_S = 0.01

S = ControllerState
SETTLES_IN: dict[str, frozenset[ControllerState]] = {
    "arm": frozenset({S.ARMED}),
    "disarm": frozenset({S.DISABLED}),
    "reset": frozenset({S.DISABLED}),
    "stop": frozenset({S.STOPPING, S.ARMED}),
    "setpoints": frozenset({S.RUNNING}),
}
"""The states a command leads to once the node has answered (a trip ends the wait too)."""

RunId = Annotated[str, Path(pattern=RUN_ID_PATTERN, description="the run's id, e.g. 20260101T120000Z-1a2b3c")]


def create_app(runtime: ServiceRuntime) -> FastAPI:
    """The API of one running service."""
    app = FastAPI(
        title="millctl controller service",
        version=__version__,
        description="The local API of `millctl serve`: watch the mill, and — holding the control lease — command "
        "it. Every command goes through the controller's interlock; E-stop is always accepted.",
    )
    install_error_handlers(app)
    app.add_middleware(BodyLimit, max_bytes=runtime.config.service.max_request_bytes)
    rt = runtime

    if rt.fault_injection:
        add_fault_routes(app, rt)

    def command(lease: str | None, what: str, action: Any, *, idle: bool = True, settles: str = "") -> CommandOut:
        """Check the lease, run ``action(controller, source)`` under the lock, and answer with the state it led to.

        The node confirms a command a few ticks later (arm → ARMED), so the answer
        waits, up to SETTLE_S, for a state in ``SETTLES_IN[settles]`` or a trip; not
        while the control loop is not running (stopped, failed, or never started, as in
        a runtime a test steps itself): then nothing ticks, and the state is as it is.
        """
        holder = rt.leases.check(lease).holder

        def run(c: Controller) -> float | None:
            if idle:
                rt.recipe.require_idle(what)
            result = action(c, holder)
            duration: float | None = getattr(result, "duration_s", None)
            return duration

        duration = rt.call(run)
        wanted = SETTLES_IN.get(settles, frozenset()) | {S.TRIPPED}
        deadline = time.monotonic() + SETTLE_S
        while (settles and rt.controller.state not in wanted and time.monotonic() < deadline and rt.running
               and not rt.stopping):
            time.sleep(SETTLE_POLL_S)
        return CommandOut(message=what, state=rt.controller.state, duration_s=duration)

    # ------------------------------------------------------------------ reading
    @app.get("/v1/status", response_model=StatusOut, responses=READ_RESPONSES, tags=["watch"])
    def status() -> dict[str, Any]:
        """The controller's status: state, setpoints, measurements, limit and margin, furnace, physics, links."""
        return rt.status()

    @app.get("/v1/service", response_model=ServiceOut, responses=READ_RESPONSES, tags=["watch"])
    def service() -> ServiceOut:
        """The running service: which mill (name, bus, simulated or not), process, config, envelope, records."""
        return rt.describe()

    @app.get("/v1/envelope", response_model=EnvelopeOut, responses=READ_RESPONSES, tags=["envelope"])
    def envelope(points: Annotated[int, Query(ge=2, le=1001)] = 41) -> EnvelopeOut:
        """The limit curve the interlock enforces: ω_v grid → ω_r limit, with the law, margin and flags."""
        return envelope_out(rt.controller.envelope, points)

    @app.post("/v1/envelope/check", response_model=CheckOut, responses=READ_RESPONSES, tags=["envelope"])
    def check(body: CheckRequest) -> CheckOut:
        """Check an operating point against the envelope; nothing is commanded."""
        verdict = rt.controller.envelope.check(body.rotary_rpm, body.vibration_rpm, body.temp_c)
        refusals = refusal_list(InterlockRefused(verdict)) if not verdict.ok else []
        return CheckOut(ok=verdict.ok, reason=verdict.reason(), limit_rotary_rpm=finite(verdict.omega_r_limit_rpm),
                        margin_rpm=finite(verdict.margin_rpm), refusals=refusals)

    @app.get("/v1/events", response_model=EventsOut, responses=READ_RESPONSES, tags=["watch"])
    def events(
        after: Annotated[int, Query(ge=0)] = 0, limit: Annotated[int, Query(ge=1, le=2000)] = 500
    ) -> EventsOut:
        """Recorded events with a sequence number above ``after``, oldest first (from a ring buffer)."""
        found = rt.journal.after(after, limit)
        return EventsOut.model_validate({"events": found, "last_seq": rt.journal.last_seq})

    @app.get(
        "/v1/stream",
        response_class=EventSourceResponse,
        responses={200: {"content": {"text/event-stream": {}},
                         "description": "server-sent events: `status` (StatusOut), `event` (EventOut, id = seq)"},
                   **READ_RESPONSES},
        tags=["watch"],
    )
    async def stream(
        count: Annotated[int | None, Query(ge=1, le=1_000_000)] = None,
        last_event_id: Annotated[int | None, Header(alias="Last-Event-ID", ge=0, description=(
            "resume: send every event after this sequence number first (still in the ring of 2000)"))] = None,
    ) -> EventSourceResponse:
        """Server-sent events: ``status`` every 0.25 s and every ``event`` as it happens (``count``: then stop).

        Each event's SSE id is its sequence number; a client that reconnects with
        ``Last-Event-ID`` gets every event it missed before the live ones.
        """
        after = rt.journal.last_seq if last_event_id is None else last_event_id
        return EventSourceResponse(_sse(rt, count, after), ping=15)

    # ------------------------------------------------------------------ control lease
    @app.get("/v1/control", response_model=ControlOut, responses=READ_RESPONSES, tags=["control"])
    def control() -> ControlOut:
        """Who holds control, and for how long."""
        return _control_out(rt)

    @app.post("/v1/control/take", response_model=LeaseOut, responses=COMMAND_RESPONSES, tags=["control"])
    def take(
        x_millctl_client: ClientName = None, x_millctl_lease: LeaseId = None,
        body: Annotated[TakeRequest | None, Body()] = None,
    ) -> LeaseOut:
        """Take control (or renew it); ``force`` takes over an expired lease, never a live one."""
        holder = client_source(x_millctl_client)
        lease, taken_from = rt.leases.take(holder, lease_id=x_millctl_lease, force=bool(body and body.force))
        if x_millctl_lease != lease.lease_id:  # a new lease, not a renewal
            note = f" (took over the expired lease of {taken_from})" if taken_from else ""
            rt.journal.add(EventKind.CONTROL, holder, f"control taken by {holder}{note}", taken_from=taken_from)
        return LeaseOut(lease_id=lease.lease_id, holder=lease.holder, ttl_s=lease.ttl_s,
                        expires_in_s=lease.remaining_s(rt.clock.now()))

    @app.post("/v1/control/release", response_model=ControlOut, responses=COMMAND_RESPONSES, tags=["control"])
    def release(x_millctl_lease: LeaseId = None) -> ControlOut:
        """Give control back (only its holder can)."""
        lease = rt.leases.release(x_millctl_lease)
        rt.journal.add(EventKind.CONTROL, lease.holder, f"control released by {lease.holder}")
        return _control_out(rt)

    # ------------------------------------------------------------------ commands
    @app.post("/v1/arm", response_model=CommandOut, responses=COMMAND_RESPONSES, tags=["command"])
    def arm(x_millctl_lease: LeaseId = None) -> CommandOut:
        """Arm the node (from DISABLED)."""
        return command(x_millctl_lease, "arm", lambda c, s: c.arm(source=s), settles="arm")

    @app.post("/v1/disarm", response_model=CommandOut, responses=COMMAND_RESPONSES, tags=["command"])
    def disarm(x_millctl_lease: LeaseId = None) -> CommandOut:
        """Disarm the node (from ARMED at standstill)."""
        return command(x_millctl_lease, "disarm", lambda c, s: c.disarm(source=s), settles="disarm")

    @app.post("/v1/stop", response_model=CommandOut, responses=COMMAND_RESPONSES, tags=["command"])
    async def stop(x_millctl_client: ClientName = None, x_millctl_lease: LeaseId = None) -> CommandOut:
        """Controlled stop (stop category 1): both drives ramp down inside the envelope, heater off.

        Needs no lease: any client may stop at any time, and a stop is run before any other command waiting
        (SAFETY 24). The record names who stopped: the lease's holder when the lease is sent, else the client.
        """
        who = rt.leases.holder_of(x_millctl_lease) or client_source(x_millctl_client)

        def act(c: Controller) -> None:
            rt.recipe.abort_if_active(who)
            c.stop(source=who)

        await rt.call_urgent(act, needs_node=True, stops=who)
        wanted = SETTLES_IN["stop"] | {S.TRIPPED}
        deadline = time.monotonic() + SETTLE_S
        while rt.controller.state not in wanted and time.monotonic() < deadline and rt.running and not rt.stopping:
            await asyncio.sleep(SETTLE_POLL_S)
        return CommandOut(message="stop", state=rt.controller.state, duration_s=None)

    @app.post("/v1/reset", response_model=CommandOut, responses=COMMAND_RESPONSES, tags=["command"])
    def reset(x_millctl_lease: LeaseId = None) -> CommandOut:
        """Clear a latched trip (fresh telemetry, both drives at standstill)."""
        return command(x_millctl_lease, "reset", lambda c, s: c.reset(source=s), settles="reset")

    @app.post("/v1/estop", response_model=CommandOut, responses=COMMAND_RESPONSES, tags=["command"])
    async def estop(x_millctl_client: ClientName = None) -> CommandOut:
        """Emergency stop: needs no lease and is always accepted, before any other command waiting."""
        who = client_source(x_millctl_client)

        def act(c: Controller) -> CommandOut:
            rt.recipe.abort_if_active(who)
            c.estop(source=who)
            return CommandOut(message="E-STOP", state=c.state)

        return await rt.call_urgent(act, stops=who)

    @app.post("/v1/setpoints", response_model=CommandOut, responses=COMMAND_RESPONSES, tags=["command"])
    def setpoints(
        body: SetpointsRequest, x_millctl_lease: LeaseId = None
    ) -> CommandOut:
        """Ramp to new drive speeds (rpm), with an optional furnace target (°C): all or nothing.

        Refused with the interlock's reason when any part is outside the envelope; then no part is applied.
        """
        furnace = "" if body.temp_c is None else f", furnace {body.temp_c:.1f} °C"
        return command(
            x_millctl_lease,
            f"setpoints ω_r = {body.rotary_rpm:.1f} rpm, ω_v = {body.vibration_rpm:.1f} rpm{furnace}",
            lambda c, s: c.set_speeds(body.rotary_rpm, body.vibration_rpm, rotary_rate_rpm_s=body.rotary_rate_rpm_s,
                                      vibration_rate_rpm_s=body.vibration_rate_rpm_s, linear=body.linear,
                                      furnace_c=body.temp_c, heating_rate_c_per_min=body.rate_c_per_min, source=s),
            settles="setpoints" if body.rotary_rpm > 0.0 or body.vibration_rpm > 0.0 else "",
        )

    @app.post("/v1/furnace", response_model=CommandOut, responses=COMMAND_RESPONSES, tags=["command"])
    def furnace(
        body: FurnaceRequest, x_millctl_lease: LeaseId = None
    ) -> CommandOut:
        """Set the furnace target (°C, ramped at the heating rate), or null to turn the heater off."""
        what = "heater off" if body.temp_c is None else f"furnace to {body.temp_c:.1f} °C"
        return command(x_millctl_lease, what,
                       lambda c, s: c.set_furnace(body.temp_c, rate_c_per_min=body.rate_c_per_min, source=s))

    # ------------------------------------------------------------------ recipes
    def recipe_action(lease: str | None, action: Any, *, arrived_s: float | None = None) -> RecipeOut:
        holder = rt.leases.check(lease, arrived_s=arrived_s).holder
        progress = rt.call(lambda c: action(holder))
        return RecipeOut(active=rt.recipe.active, progress=RecipeProgress.model_validate(finite(progress)))

    @app.get("/v1/recipe", response_model=RecipeOut, responses=READ_RESPONSES, tags=["recipe"])
    def recipe() -> RecipeOut:
        """Progress of the current (or last) recipe run."""
        return rt.recipe_view()

    @app.post("/v1/recipe/run", response_model=RecipeOut, responses=COMMAND_RESPONSES, tags=["recipe"])
    def recipe_run(body: RecipeRunRequest, x_millctl_lease: LeaseId = None) -> RecipeOut:
        """Pre-flight and start a recipe sent as its TOML text; refused with every violation if it leaves the envelope.

        The service opens no path a request names: a client may be on another machine.
        """
        arrived_s = rt.clock.now()
        rt.leases.check(x_millctl_lease)
        loaded, plan = rt.recipe.prepare(body.name, body.text, rt.config)  # in this request's thread, not the loop
        run_id, lock = rt.recipe.lock_new_run()  # its record's lock: a live run is never taken for an interrupted one
        try:  # checked again: taken over meanwhile is refused; a pre-flight longer than the lease's life is not
            return recipe_action(x_millctl_lease, lambda who: rt.recipe.start(loaded, plan, who, run_id=run_id,
                                                                             lock=lock, text=body.text),
                                 arrived_s=arrived_s)
        except BaseException:
            lock.release(remove_if_empty=True)
            raise

    @app.get("/v1/recipe/unfinished", response_model=UnfinishedRunsOut, responses=READ_RESPONSES, tags=["recipe"])
    def recipe_unfinished() -> UnfinishedRunsOut:
        """The interrupted runs in the records (the service stopped or died under them), oldest first."""
        return UnfinishedRunsOut(runs=[unfinished_out(h) for h in rt.recipe.unfinished()])

    @app.post("/v1/recipe/unfinished/{run_id}/resume", response_model=RecipeResumeOut,
              responses={**COMMAND_RESPONSES, 404: {"model": ErrorBody, "description": "no run record with this id"}},
              tags=["recipe"])
    def recipe_resume_run(run_id: RunId, body: RecipeResumeRequest,
                          x_millctl_lease: LeaseId = None) -> RecipeResumeOut:
        """Check (``confirm`` false) or resume (``confirm`` true) an interrupted run, from the mill's state now.

        Refused (409) for a run that ended, one that runs, a recipe text or a configuration that changed since the
        run started, and when the pre-flight finds a problem (each is named); the run then stays interrupted.
        """
        holder = rt.leases.check(x_millctl_lease).holder
        prepared = rt.recipe.prepare_resume(run_id, body.text, rt.loaded.sha256, rt.config)  # the disk: not the loop
        shown = unfinished_out(prepared.history)
        if not body.confirm:
            check = rt.call(lambda c: rt.recipe.check_out(rt.recipe.check_resume(prepared)), needs_node=False)
            return RecipeResumeOut(run=shown, check=check, started=False, recipe=None)
        lock = RunLock.acquire(prepared.history.path)  # one resume at a time, across services too
        try:
            torn = repair_tail(prepared.history.path)

            def start(c: Controller) -> RecipeResumeOut:
                check = rt.recipe.check_out(rt.recipe.check_resume(prepared))
                rt.recipe.resume_run(prepared, lock, torn, holder)
                return RecipeResumeOut(run=shown, check=check, started=True, recipe=rt.recipe.recipe_out())

            return rt.call(start, needs_node=False)  # the check names a missing node with the other problems
        except BaseException:
            lock.release()
            raise

    @app.post("/v1/recipe/unfinished/{run_id}/abort", response_model=UnfinishedRunOut,
              responses={**COMMAND_RESPONSES, 404: {"model": ErrorBody, "description": "no run record with this id"}},
              tags=["recipe"])
    def recipe_close_run(run_id: RunId, x_millctl_lease: LeaseId = None) -> UnfinishedRunOut:
        """Close an interrupted run for good (its record ends ABORTED); nothing moves."""
        holder = rt.leases.check(x_millctl_lease).holder
        closed = rt.recipe.close_interrupted(run_id, holder)
        rt.journal.add(EventKind.SERVICE, holder, f"interrupted run {run_id} closed by {holder} (ABORTED)",
                       run_id=run_id)
        out = unfinished_out(closed)
        return out.model_copy(update={"state": RunState.ABORTED})

    @app.post("/v1/recipe/check", response_model=RecipeCheckOut, responses=READ_RESPONSES, tags=["recipe"])
    def recipe_check(body: RecipeRunRequest) -> RecipeCheckOut:
        """Pre-flight a recipe sent as its TOML text against this service's envelope; nothing is started.

        Answers 200 for a recipe that would be refused too, with every problem: a client can list recipes
        with their verdicts (the TUI's recipe list) without holding control.
        """
        return rt.recipe.check(body.name, body.text, rt.config)

    @app.post("/v1/recipe/pause", response_model=RecipeOut, responses=COMMAND_RESPONSES, tags=["recipe"])
    def recipe_pause(
        x_millctl_lease: LeaseId = None, body: Annotated[RecipePauseRequest | None, Body()] = None
    ) -> RecipeOut:
        """Pause the run at the next step boundary, or ``now`` (holding the current setpoints)."""
        now = bool(body and body.now)
        return recipe_action(x_millctl_lease, lambda who: rt.recipe.pause(now, who))

    @app.post("/v1/recipe/resume", response_model=RecipeOut, responses=COMMAND_RESPONSES, tags=["recipe"])
    def recipe_resume(x_millctl_lease: LeaseId = None) -> RecipeOut:
        """Resume a paused or held run."""
        return recipe_action(x_millctl_lease, lambda who: rt.recipe.resume(who))

    @app.post("/v1/recipe/abort", response_model=RecipeOut, responses=COMMAND_RESPONSES, tags=["recipe"])
    def recipe_abort(x_millctl_lease: LeaseId = None) -> RecipeOut:
        """Abort the run with a controlled stop."""
        return recipe_action(x_millctl_lease, lambda who: rt.recipe.abort(who))

    return app


def _control_out(rt: ServiceRuntime) -> ControlOut:
    lease = rt.leases.current
    if lease is None:
        return ControlOut(held=False, holder=None, expires_in_s=None, expired=False)
    remaining = lease.remaining_s(rt.clock.now())
    return ControlOut(held=True, holder=lease.holder, expires_in_s=remaining, expired=remaining <= 0.0)


async def _sse(rt: ServiceRuntime, count: int | None, after: int) -> AsyncIterator[ServerSentEvent]:
    """Every event after ``after``, then status every STATUS_PERIOD_S and each new event, until the service stops.

    sse-starlette ends the generator when the client leaves.
    """
    loop = asyncio.get_running_loop()
    last_seq = after
    next_status_s = loop.time()
    sent = 0
    while not rt.stopping and (count is None or sent < count):
        for event in rt.journal.after(last_seq):
            last_seq = event["seq"]
            yield ServerSentEvent(data=_json(event), event=StreamKind.EVENT.value, id=str(last_seq))
            sent += 1
            if count is not None and sent >= count:
                return
        if loop.time() >= next_status_s:
            status = await run_in_threadpool(rt.status)
            yield ServerSentEvent(data=_json(status), event=StreamKind.STATUS.value)
            sent += 1
            next_status_s += STATUS_PERIOD_S
        await asyncio.sleep(STREAM_POLL_S)


def _json(data: Any) -> str:
    return json.dumps(data, ensure_ascii=False, default=str)


__all__ = ["STATUS_PERIOD_S", "create_app"]

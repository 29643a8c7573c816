"""The client's table of operations, one row a call: how its arguments become a :class:`Request`, and its model.

:class:`Operation` is the descriptor the clients (:mod:`millctl.client`) are built
from: an attribute of :class:`~millctl.client.Client` is a method returning the
answer's model, of :class:`~millctl.client.AsyncClient` a coroutine method. The
builders below say, once for both clients, which route each call takes and
what its body or query carries.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, ParamSpec, TypeVar, overload
from urllib.parse import quote

from pydantic import BaseModel

from millctl.api import SimFaultName
from millctl.errors import InvalidInputError
from millctl.files import FileRefused, read_input_text

if TYPE_CHECKING:
    from millctl.client import AsyncClient, Client, _Base

P = ParamSpec("P")
T = TypeVar("T", bound=BaseModel)


def read_recipe_text(path: str | os.PathLike[str]) -> tuple[str, str]:
    """A recipe file's name and text, read on the client's side (the service opens no path a request names)."""
    path = Path(path)
    try:
        return path.name, read_input_text(path)
    except FileRefused as exc:
        raise InvalidInputError(f"recipe {path}: cannot read it: {exc}") from None


@dataclass(frozen=True)
class Request:
    """One API call, before it is sent: method, path, JSON body, query."""

    method: str
    path: str
    body: dict[str, Any] | None = None
    params: dict[str, Any] | None = None


class Operation(Generic[P, T]):
    """One row of the table: how the call's arguments become a :class:`Request`, and the model of the answer.

    As an attribute of :class:`Client` it is a method returning ``T``; of
    :class:`AsyncClient`, a coroutine method returning ``T``.
    """

    def __init__(self, out: type[T], build: Callable[P, Request]) -> None:
        self.out = out
        self.build = build

    @overload
    def __get__(self, client: None, owner: type[Any]) -> Operation[P, T]: ...
    @overload
    def __get__(self, client: Client, owner: type[Any]) -> Callable[P, T]: ...
    @overload
    def __get__(self, client: AsyncClient, owner: type[Any]) -> Callable[P, Awaitable[T]]: ...

    def __get__(self, client: _Base | None, owner: type[Any]) -> Any:
        if client is None:
            return self
        perform = client._perform

        @functools.wraps(self.build)
        def call(*args: P.args, **kwargs: P.kwargs) -> Any:
            return perform(self, self.build(*args, **kwargs))

        return call


def _get(path: str, **params: Any) -> Request:
    return Request("GET", path, params=params or None)


def _post(path: str, body: dict[str, Any] | None = None) -> Request:
    return Request("POST", path, body)


def _status() -> Request:
    """The controller's status (GET /v1/status)."""
    return _get("/v1/status")


def _service() -> Request:
    """The running service: pid, config path and sha256, law, margin (GET /v1/service)."""
    return _get("/v1/service")


def _envelope(points: int = 41) -> Request:
    """The enforced limit curve on ``points`` vibration speeds (GET /v1/envelope)."""
    return _get("/v1/envelope", points=points)


def _check(rotary_rpm: float, vibration_rpm: float, temp_c: float | None = None) -> Request:
    """Check a point against the envelope without commanding anything (POST /v1/envelope/check)."""
    return _post("/v1/envelope/check", {"rotary_rpm": rotary_rpm, "vibration_rpm": vibration_rpm, "temp_c": temp_c})


def _events(after: int = 0, limit: int = 500) -> Request:
    """Recorded events after sequence number ``after`` (GET /v1/events)."""
    return _get("/v1/events", after=after, limit=limit)


def _control_state() -> Request:
    """Who holds control (GET /v1/control)."""
    return _get("/v1/control")


def _take(force: bool = False) -> Request:
    """Take (or renew) the control lease; ``force`` takes over an expired one (POST /v1/control/take)."""
    return _post("/v1/control/take", {"force": force})


def _release() -> Request:
    """Give control back (POST /v1/control/release)."""
    return _post("/v1/control/release")


def _arm() -> Request:
    """Arm (needs control)."""
    return _post("/v1/arm")


def _disarm() -> Request:
    """Disarm (needs control)."""
    return _post("/v1/disarm")


def _stop() -> Request:
    """Controlled stop (needs control); aborts a running recipe."""
    return _post("/v1/stop")


def _estop() -> Request:
    """Emergency stop (no control needed, always accepted)."""
    return _post("/v1/estop")


def _reset() -> Request:
    """Clear a latched trip (needs control)."""
    return _post("/v1/reset")


def _set_speeds(
    rotary_rpm: float,
    vibration_rpm: float,
    *,
    rotary_rate_rpm_s: float | None = None,
    vibration_rate_rpm_s: float | None = None,
    linear: bool = False,
    temp_c: float | None = None,
    rate_c_per_min: float | None = None,
) -> Request:
    """Ramp to new speeds (rpm), with an optional furnace target (°C), all or nothing (needs control).

    An :class:`InterlockRefusal` when any part is outside the envelope: then no part is applied.
    """
    return _post("/v1/setpoints", {"rotary_rpm": rotary_rpm, "vibration_rpm": vibration_rpm,
                                   "rotary_rate_rpm_s": rotary_rate_rpm_s,
                                   "vibration_rate_rpm_s": vibration_rate_rpm_s, "linear": linear,
                                   "temp_c": temp_c, "rate_c_per_min": rate_c_per_min})


def _set_furnace(temp_c: float | None, *, rate_c_per_min: float | None = None) -> Request:
    """Furnace target (°C), or None for heater off (needs control)."""
    return _post("/v1/furnace", {"temp_c": temp_c, "rate_c_per_min": rate_c_per_min})


def _recipe_run(path: str | os.PathLike[str]) -> Request:
    """Start a recipe file: read here and sent by content, never as a path on the service's disk (needs control)."""
    name, text = read_recipe_text(path)
    return _recipe_run_text(name, text)


def _recipe_run_text(name: str, text: str) -> Request:
    """Start a recipe given as its TOML text, recorded under ``name`` (needs control)."""
    return _post("/v1/recipe/run", {"name": name, "text": text})


def _recipe_check(path: str | os.PathLike[str]) -> Request:
    """Pre-flight a recipe file against the service's envelope: read here, sent by content; nothing starts."""
    name, text = read_recipe_text(path)
    return _recipe_check_text(name, text)


def _recipe_check_text(name: str, text: str) -> Request:
    """Pre-flight a recipe given as its TOML text, under ``name``; nothing starts (no control needed)."""
    return _post("/v1/recipe/check", {"name": name, "text": text})


def _faults() -> Request:
    """The faults injected into the simulated node (GET /v1/sim/faults; serve --fault-injection only)."""
    return _get("/v1/sim/faults")


def _inject_fault(fault: SimFaultName | str, active: bool = True, param: float = 0.0) -> Request:
    """Inject (or clear) a simulated node fault for an operator drill (serve --fault-injection only)."""
    return _post("/v1/sim/faults", {"fault": str(fault), "active": active, "param": param})


def _recipe_pause(now: bool = False) -> Request:
    """Pause the run at the next step boundary, or now."""
    return _post("/v1/recipe/pause", {"now": now})


def _recipe_resume() -> Request:
    """Resume a paused or held run."""
    return _post("/v1/recipe/resume")


def _recipe_abort() -> Request:
    """Abort the run (controlled stop)."""
    return _post("/v1/recipe/abort")


def _recipe() -> Request:
    """Progress of the current or last run (GET /v1/recipe)."""
    return _get("/v1/recipe")


def _recipe_unfinished() -> Request:
    """The interrupted runs in the service's records (GET /v1/recipe/unfinished)."""
    return _get("/v1/recipe/unfinished")


def _recipe_resume_run(run_id: str, *, confirm: bool, text: str | None = None) -> Request:
    """Check (``confirm`` false) or resume an interrupted run; ``text``: the recipe, if the record keeps none."""
    return _post(f"/v1/recipe/unfinished/{quote(run_id, safe='')}/resume", {"confirm": confirm, "text": text})


def _recipe_close_run(run_id: str) -> Request:
    """Close an interrupted run for good: its record ends ABORTED (needs control)."""
    return _post(f"/v1/recipe/unfinished/{quote(run_id, safe='')}/abort")


__all__ = ["Operation", "Request", "read_recipe_text"]

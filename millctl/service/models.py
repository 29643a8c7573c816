"""Request and response models of the service API (``/v1``): every request is validated, unknown fields refused.

The status model is derived from :class:`millctl.controller.Status`, so the API
can never drift from what the controller reports; every float in it may be
null (a non-finite value, e.g. an unbounded limit, is sent as null).
"""

from __future__ import annotations

import typing
from dataclasses import fields
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, create_model

from millctl.controller import Status


class Strict(BaseModel):
    """A request or response body: unknown fields are an error."""

    model_config = ConfigDict(extra="forbid")


Rpm = Annotated[float, Field(ge=0.0, le=100_000.0, allow_inf_nan=False)]
RpmPerS = Annotated[float, Field(gt=0.0, le=100_000.0, allow_inf_nan=False)]


# ---------------------------------------------------------------- errors
class Refusal(Strict):
    """One quantity outside the envelope: its value, the limit and why."""

    quantity: str
    value: float | None
    limit: float | None
    unit: str
    reason: str


class ErrorBody(Strict):
    """Every error of the API: a stable code, a message naming the value and the bound, the field if any."""

    code: str = Field(description="stable machine-readable code, e.g. interlock_refused, control_held, invalid_request")
    message: str
    field: str | None = None
    holder: str | None = Field(default=None, description="who holds control (code control_held)")
    refusals: list[Refusal] = Field(default_factory=list, description="the interlock's refusals (interlock_refused)")


# ---------------------------------------------------------------- status
def _nullable(annotation: Any) -> Any:
    """The annotation with None allowed wherever a float may be non-finite."""
    if annotation is float:
        return float | None
    return annotation


_STATUS_HINTS = typing.get_type_hints(Status)
StatusOut: type[BaseModel] = create_model(  # type: ignore[call-overload]
    "StatusOut",
    __doc__="A snapshot of the controller (as :class:`millctl.controller.Status`; non-finite floats as null).",
    **{f.name: (_nullable(_STATUS_HINTS[f.name]), ...) for f in fields(Status)},
)


# ---------------------------------------------------------------- envelope
class EnvelopePoint(Strict):
    """The enforced limit at one vibration speed."""

    omega_v_rpm: float
    omega_r_limit_rpm: float | None = Field(description="enforced rotary limit, margin applied (rpm)")
    law_limit_rpm: float | None = Field(description="the law's limit without margin (rpm)")
    law_is_every_cycle: bool


class EnvelopeOut(Strict):
    """The limit curve the interlock enforces, and what it is built from (SAFETY 14: shown)."""

    law: str
    description: str
    margin: float
    rotary_max_rpm: float
    vibration_max_rpm: float
    furnace_min_c: float
    furnace_max_c: float
    max_heating_rate_c_per_min: float
    points: list[EnvelopePoint]


class CheckRequest(Strict):
    """An operating point to check against the envelope (nothing is commanded)."""

    rotary_rpm: float = Field(allow_inf_nan=False, ge=-100_000.0, le=100_000.0)
    vibration_rpm: float = Field(allow_inf_nan=False, ge=-100_000.0, le=100_000.0)
    temp_c: float | None = Field(default=None, allow_inf_nan=False, ge=-1_000.0, le=10_000.0)


class CheckOut(Strict):
    """The envelope's verdict on one point."""

    ok: bool
    reason: str
    omega_r_limit_rpm: float | None
    margin_rpm: float | None
    refusals: list[Refusal]


# ---------------------------------------------------------------- control lease
class TakeRequest(Strict):
    """Ask for control; ``force`` takes over a lease whose holder stopped renewing it (never a live one)."""

    force: bool = False


class LeaseOut(Strict):
    """The control lease: send ``lease_id`` in the ``X-Millctl-Lease`` header of every command."""

    lease_id: str
    holder: str
    expires_in_s: float
    ttl_s: float


class ControlOut(Strict):
    """Who holds control now (no lease id: only its holder knows it)."""

    held: bool
    holder: str | None
    expires_in_s: float | None
    expired: bool


# ---------------------------------------------------------------- commands
class SetpointsRequest(Strict):
    """New drive speeds; the controller plans a ramp inside the envelope or refuses."""

    rotary_rpm: Rpm
    vibration_rpm: Rpm
    rotary_rate_rpm_s: RpmPerS | None = None
    vibration_rate_rpm_s: RpmPerS | None = None
    linear: bool = False
    temp_c: float | None = Field(
        default=None, allow_inf_nan=False, ge=-1_000.0, le=10_000.0,
        description="furnace target (°C) set together with the speeds: all or nothing",
    )
    rate_c_per_min: float | None = Field(default=None, allow_inf_nan=False, gt=0.0, le=10_000.0)


class FurnaceRequest(Strict):
    """A furnace target (°C), or null to turn the heater off."""

    temp_c: float | None = Field(allow_inf_nan=False, ge=-1_000.0, le=10_000.0)
    rate_c_per_min: float | None = Field(default=None, allow_inf_nan=False, gt=0.0, le=10_000.0)


class CommandOut(Strict):
    """A command was accepted: what was done and the state right after."""

    accepted: Literal[True] = True
    message: str
    state: str
    duration_s: float | None = Field(default=None, description="planned ramp duration (setpoints)")


# ---------------------------------------------------------------- events, service
class EventOut(Strict):
    """One recorded event (state change, command, refusal, trip, control, service)."""

    seq: int
    t: float = Field(description="Unix time (s)")
    time_s: float | None = Field(description="controller clock (s)")
    kind: str
    source: str
    message: str
    data: dict[str, Any]


class EventsOut(Strict):
    """Events after a sequence number, oldest first (a ring buffer: old ones drop out)."""

    events: list[EventOut]
    last_seq: int


class ServiceOut(Strict):
    """The running service: process, config, envelope law and margin, records."""

    pid: int
    version: str
    started_unix: float
    config_path: str
    config_sha256: str
    law: str
    margin: float
    bus_interface: str
    bus_channel: str
    embedded_node: bool
    records_dir: str


# ---------------------------------------------------------------- recipes
class RecipeRunRequest(Strict):
    """Run the recipe file at ``path`` (on the service's machine)."""

    path: str = Field(min_length=1, max_length=4096)


class RecipePauseRequest(Strict):
    """Pause the running recipe: at the end of the step, or ``now``."""

    now: bool = False


class RecipeOut(Strict):
    """Progress of the current (or last) recipe run; ``active`` false when none."""

    active: bool
    progress: dict[str, Any]


__all__ = [
    "CheckOut",
    "CheckRequest",
    "CommandOut",
    "ControlOut",
    "EnvelopeOut",
    "EnvelopePoint",
    "ErrorBody",
    "EventOut",
    "EventsOut",
    "FurnaceRequest",
    "LeaseOut",
    "RecipeOut",
    "RecipePauseRequest",
    "RecipeRunRequest",
    "Refusal",
    "ServiceOut",
    "SetpointsRequest",
    "StatusOut",
    "Strict",
    "TakeRequest",
]

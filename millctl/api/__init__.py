"""The typed contract of the service API: the request and response models and the enumerations, defined once.

The service (:mod:`millctl.service`) validates with these models and
documents them in its OpenAPI schema; the clients (:mod:`millctl.client`)
return them; the CLI and the TUI read them. Nothing here imports the
controller, so every part of millctl may import it.
"""

from millctl.api.enums import (
    BusCondition,
    ControllerState,
    ErrorCode,
    EventKind,
    RunState,
    SimFaultName,
    StreamKind,
)
from millctl.api.models import (
    BusHealthOut,
    BusReceiveOut,
    CheckOut,
    CheckRequest,
    CommandOut,
    ControlOut,
    EnvelopeOut,
    EnvelopePoint,
    ErrorBody,
    EventOut,
    EventsOut,
    FaultRequest,
    FaultsOut,
    FurnaceRequest,
    LeaseOut,
    LinkOut,
    RecipeCheckOut,
    RecipeOut,
    RecipePauseRequest,
    RecipeProgress,
    RecipeRunRequest,
    Refusal,
    RegimeOut,
    ServiceOut,
    SetpointsRequest,
    StatusOut,
    Strict,
    TakeRequest,
)

API_VERSION = "v1"
"""The path prefix of every route."""

__all__ = [
    "API_VERSION",
    "BusCondition",
    "BusHealthOut",
    "BusReceiveOut",
    "CheckOut",
    "CheckRequest",
    "CommandOut",
    "ControlOut",
    "ControllerState",
    "EnvelopeOut",
    "EnvelopePoint",
    "ErrorBody",
    "ErrorCode",
    "EventKind",
    "EventOut",
    "EventsOut",
    "FaultRequest",
    "FaultsOut",
    "FurnaceRequest",
    "LeaseOut",
    "LinkOut",
    "RecipeCheckOut",
    "RecipeOut",
    "RecipePauseRequest",
    "RecipeProgress",
    "RecipeRunRequest",
    "Refusal",
    "RegimeOut",
    "RunState",
    "ServiceOut",
    "SetpointsRequest",
    "SimFaultName",
    "StatusOut",
    "StreamKind",
    "Strict",
    "TakeRequest",
]

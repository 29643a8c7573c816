"""The typed contract of the service API: the request and response models and the enumerations, defined once.

The service (:mod:`millctl.service`) validates with these models and
documents them in its OpenAPI schema; the clients (:mod:`millctl.client`)
return them; the CLI and the TUI read them. Nothing here imports the
controller, so every part of millctl may import it. The enumerations load with the package; the models (and
pydantic with them) on first use, so that a command that needs no model starts without pydantic.
"""

from typing import TYPE_CHECKING, Any

from millctl.api.enums import (
    BusCondition,
    ControllerState,
    ErrorCode,
    EventKind,
    RunState,
    SimFaultName,
    StreamKind,
)

if TYPE_CHECKING:
    from millctl.api.models import (
        BusHealthOut,
        BusReceiveOut,
        CheckOut,
        CheckRequest,
        CommandOut,
        ControlOut,
        DriveOut,
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
        Refusal,
        RegimeOut,
        ServiceOut,
        SetpointsRequest,
        StatusOut,
        Strict,
        TakeRequest,
    )
    from millctl.api.recipe_models import (
        RecipeCheckOut,
        RecipeOut,
        RecipePauseRequest,
        RecipeProgress,
        RecipeResumeOut,
        RecipeResumeRequest,
        RecipeRunRequest,
        ResumeCheckOut,
        RunGapOut,
        UnfinishedRunOut,
        UnfinishedRunsOut,
    )

_MODEL_MODULES = ("millctl.api.models", "millctl.api.recipe_models")
"""Where the models are defined, imported by :func:`__getattr__` on first use."""

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
    "DriveOut",
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
    "RecipeResumeOut",
    "RecipeResumeRequest",
    "RecipeRunRequest",
    "Refusal",
    "RegimeOut",
    "ResumeCheckOut",
    "RunGapOut",
    "RunState",
    "ServiceOut",
    "SetpointsRequest",
    "SimFaultName",
    "StatusOut",
    "StreamKind",
    "Strict",
    "TakeRequest",
    "UnfinishedRunOut",
    "UnfinishedRunsOut",
]


def __getattr__(name: str) -> Any:
    """A model of the API, imported on first use (keeps ``import millctl.api`` free of pydantic)."""
    import importlib

    if name in __all__:
        for module in _MODEL_MODULES:
            defined = importlib.import_module(module)
            if name in defined.__all__:
                value = getattr(defined, name)
                globals()[name] = value
                return value
    raise AttributeError(f"module 'millctl.api' has no attribute {name!r}")

"""How the API reports errors: JSON ``{"code", "message", "field"}`` with a stable code and the right status.

=====  ======================  ====================================================
409    ``interlock_refused``   the envelope refused it (with every refusal)
409    ``recipe_refused``      a recipe's pre-flight plan leaves the envelope
409    ``wrong_state``         the state machine (or a running recipe) refused it
422    ``invalid_request``     validation failed (``field`` names the field)
422    ``invalid_input``       a recipe's text is not a valid recipe (the field is named)
423    ``control_held``        another client holds control (``holder`` names it)
401    ``unauthorized``        TCP without the right bearer token (see auth.py)
503    ``node_unreachable``    no node on the bus, or the control loop is down
503    ``busy``                the control loop's command queue is full (nothing was done)
413    ``body_too_large``      a request body over ``service.max_request_bytes`` (see limits.py)
404    ``run_not_found``       no run record with this id (or not a readable one)
=====  ======================  ====================================================
"""

from __future__ import annotations

import math
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException

from millctl.api import ErrorBody, ErrorCode
from millctl.errors import InterlockError, InvalidInputError
from millctl.recipes.history import RunNotFound
from millctl.safety import InterlockRefused
from millctl.service.lease import LeaseError
from millctl.service.recipe import RecipeRefused
from millctl.service.runtime import NodeUnreachable, ServiceBusy


def _num(value: float) -> float | None:
    return value if math.isfinite(value) else None


def error_response(status: int, code: ErrorCode, message: str, **extra: Any) -> JSONResponse:
    """A JSON error response in the one shape every error has."""
    body = ErrorBody(code=code, message=message, **extra)
    return JSONResponse(status_code=status, content=body.model_dump(exclude_defaults=True))


def refusal_list(refused: InterlockRefused) -> list[dict[str, Any]]:
    """The interlock's refusals as plain data: quantity, value, limit, unit, reason."""
    return [
        {"quantity": r.quantity, "value": _num(r.value), "limit": _num(r.limit), "unit": r.unit, "reason": r.reason}
        for r in refused.verdict.refusals
    ]


async def _validation(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    errors = exc.errors()
    first = errors[0] if errors else {"loc": (), "msg": "invalid request"}
    field = ".".join(str(part) for part in first.get("loc", ()))
    parts = [f"{'.'.join(str(p) for p in e.get('loc', ()))}: {e.get('msg', '')}" for e in errors[:5]]
    return error_response(422, ErrorCode.INVALID_REQUEST, "; ".join(parts) or "invalid request", field=field or None)


async def _interlock_refused(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, InterlockRefused)
    refusals = refusal_list(exc)
    field = refusals[0]["quantity"] if refusals else None
    return error_response(409, ErrorCode.INTERLOCK_REFUSED, str(exc), field=field, refusals=refusals)


async def _recipe_refused(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RecipeRefused)
    refusals = [
        {"quantity": v.quantity, "value": _num(v.value), "limit": _num(v.limit), "unit": "", "reason": str(v)}
        for v in exc.violations
    ]
    return error_response(409, ErrorCode.RECIPE_REFUSED, str(exc), field="path", refusals=refusals)


async def _lease(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, LeaseError)
    return error_response(423, ErrorCode.CONTROL_HELD, str(exc), field="X-Millctl-Lease", holder=exc.holder)


async def _interlock(request: Request, exc: Exception) -> JSONResponse:
    return error_response(409, ErrorCode.WRONG_STATE, str(exc))


async def _invalid_input(request: Request, exc: Exception) -> JSONResponse:
    return error_response(422, ErrorCode.INVALID_INPUT, str(exc), field="text")


async def _run_not_found(request: Request, exc: Exception) -> JSONResponse:
    return error_response(404, ErrorCode.RUN_NOT_FOUND, str(exc), field="run_id")


async def _unreachable(request: Request, exc: Exception) -> JSONResponse:
    return error_response(503, ErrorCode.NODE_UNREACHABLE, str(exc))


async def _busy(request: Request, exc: Exception) -> JSONResponse:
    return error_response(503, ErrorCode.BUSY, str(exc))


async def _http(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, HTTPException)
    if exc.status_code == 400:  # a body that is not JSON at all: a validation error like any other
        return error_response(422, ErrorCode.INVALID_REQUEST, f"body: {exc.detail}", field="body")
    return error_response(exc.status_code, ErrorCode.HTTP_ERROR, f"HTTP {exc.status_code}: {exc.detail}")


def install_error_handlers(app: FastAPI) -> None:
    """Map every exception the routes may raise to its JSON error (the most specific class wins)."""
    app.add_exception_handler(RequestValidationError, _validation)
    app.add_exception_handler(InterlockRefused, _interlock_refused)
    app.add_exception_handler(RecipeRefused, _recipe_refused)
    app.add_exception_handler(LeaseError, _lease)
    app.add_exception_handler(InterlockError, _interlock)
    app.add_exception_handler(InvalidInputError, _invalid_input)
    app.add_exception_handler(RunNotFound, _run_not_found)
    app.add_exception_handler(NodeUnreachable, _unreachable)
    app.add_exception_handler(ServiceBusy, _busy)
    app.add_exception_handler(HTTPException, _http)


ERROR = {"model": ErrorBody}
READ_RESPONSES: dict[int | str, dict[str, Any]] = {
    401: {**ERROR, "description": "TCP request without the right bearer token"},
    413: {**ERROR, "description": "request body over service.max_request_bytes"},
    422: {**ERROR, "description": "invalid request (the field is named)"},
    503: {**ERROR, "description": "the control loop is down or its queue is full"},
}
COMMAND_RESPONSES: dict[int | str, dict[str, Any]] = {
    **READ_RESPONSES,
    409: {**ERROR, "description": "refused by the interlock (with its reason and refusals) or by the state"},
    423: {**ERROR, "description": "control is held by another client (the holder is named), or no lease"},
    503: {**ERROR, "description": "the node is unreachable, the control loop is down or its queue is full"},
}

__all__ = ["COMMAND_RESPONSES", "ERROR", "READ_RESPONSES", "error_response", "install_error_handlers", "refusal_list"]

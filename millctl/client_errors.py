"""The exceptions of the service client, each with its exit code, and the mapping from an API error to them.

=====  ======================================  =======================  ====
HTTP   API code                                exception                exit
=====  ======================================  =======================  ====
409    interlock_refused, recipe_refused       :class:`InterlockRefusal`  2
409    wrong_state                             :class:`ServiceRefused`    2
423    control_held                            :class:`ControlHeld`       2
422    invalid_request, invalid_input          :class:`RequestInvalid`    1
404    run_not_found                           :class:`RequestInvalid`    1
401    unauthorized                            :class:`AccessDenied`      3
503    node_unreachable                        :class:`NodeUnavailable`   3
—      (nothing answers)                       :class:`ServiceUnavailable` 3
=====  ======================================  =======================  ====

All are exported from :mod:`millctl` as well.
"""

from __future__ import annotations

import httpx
from pydantic import ValidationError

from millctl.api import ErrorBody, ErrorCode, Refusal
from millctl.errors import BusError, InterlockError, InvalidInputError


class ServiceUnavailable(BusError):
    """No service answers on the socket (or URL): start it with ``millctl serve``."""


class AccessDenied(BusError, PermissionError):
    """The socket's permissions, or the bearer token, keep this client out."""


class NodeUnavailable(BusError):
    """The service runs, but the node is unreachable or the control loop is down (HTTP 503)."""


class ServiceRefused(InterlockError):
    """The service refused a command (wrong state, or a running recipe); ``error`` is the API's error body."""

    def __init__(self, message: str, error: ErrorBody | None = None) -> None:
        self.error = error or ErrorBody(code=ErrorCode.WRONG_STATE, message=message)
        self.code = self.error.code
        self.reason = self.error.message
        super().__init__(message)


class InterlockRefusal(ServiceRefused):
    """The interlock refused a command; ``refusals`` lists quantity, value, limit, unit and reason."""

    @property
    def refusals(self) -> list[Refusal]:
        """Each out-of-envelope quantity with its value and limit."""
        return list(self.error.refusals)


class ControlHeld(ServiceRefused):
    """Another client holds control (``holder``), or this client has no valid lease (HTTP 423)."""

    @property
    def holder(self) -> str | None:
        """Who holds control."""
        return self.error.holder


class RequestInvalid(InvalidInputError):
    """The service rejected the request as invalid (HTTP 422); ``field`` names the field."""

    def __init__(self, message: str, field: str | None = None) -> None:
        self.field = field
        super().__init__(message)


def _error_body(response: httpx.Response) -> ErrorBody:
    """The response's error body; one made from the status line when the body is not the API's."""
    try:
        return ErrorBody.model_validate_json(response.content)
    except ValidationError:
        text = response.text or response.reason_phrase
        return ErrorBody(code=ErrorCode.HTTP_ERROR, message=f"HTTP {response.status_code}: {text}")


def raise_for_error(response: httpx.Response, where: str) -> None:
    """Turn an API error response into the matching millctl exception."""
    status = response.status_code
    if status < 400:
        return
    error = _error_body(response)
    message = error.message
    if status == 409 and error.code in (ErrorCode.INTERLOCK_REFUSED, ErrorCode.RECIPE_REFUSED):
        raise InterlockRefusal(message, error)
    if status == 423:
        raise ControlHeld(message, error)
    if status == 409:
        raise ServiceRefused(message, error)
    if status == 422 or (status == 404 and error.code is ErrorCode.RUN_NOT_FOUND):
        raise RequestInvalid(message, error.field)
    if status == 401:
        raise AccessDenied(f"{where}: {message}")
    if status == 503:
        raise NodeUnavailable(f"{where}: {message}")
    raise BusError(f"{where}: HTTP {status} {error.code}: {message}")


__all__ = [
    "AccessDenied",
    "ControlHeld",
    "InterlockRefusal",
    "NodeUnavailable",
    "RequestInvalid",
    "ServiceRefused",
    "ServiceUnavailable",
    "raise_for_error",
]

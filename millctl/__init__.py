"""millctl: control and test-bench software for a horizontal vibratory rod mill.

The physics comes from the paper "Modelling and development of a horizontal vibratory
rod mill for mechanical alloying" (docs/model.md); the
interlock that keeps the mill inside the eq. 9 detachment envelope lives in
:mod:`millctl.safety`.
"""

from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from millctl.client import AsyncClient, Client
    from millctl.client_errors import (
        AccessDenied,
        ControlHeld,
        InterlockRefusal,
        NodeUnavailable,
        RequestInvalid,
        ServiceRefused,
        ServiceUnavailable,
    )

try:
    __version__ = version("millctl")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

_CLIENT_ERRORS = ("AccessDenied", "ControlHeld", "InterlockRefusal", "NodeUnavailable", "RequestInvalid",
                  "ServiceRefused", "ServiceUnavailable")

__all__ = [
    "AccessDenied",
    "AsyncClient",
    "Client",
    "ControlHeld",
    "InterlockRefusal",
    "NodeUnavailable",
    "RequestInvalid",
    "ServiceRefused",
    "ServiceUnavailable",
    "__version__",
]


def __getattr__(name: str) -> Any:
    """``millctl.Client``, ``millctl.AsyncClient`` and the client's exceptions, imported on first use.

    (Keeps ``import millctl`` light.)
    """
    if name in ("Client", "AsyncClient"):
        from millctl import client

        return getattr(client, name)
    if name in _CLIENT_ERRORS:
        from millctl import client_errors

        return getattr(client_errors, name)
    raise AttributeError(f"module 'millctl' has no attribute {name!r}")

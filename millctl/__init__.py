"""millctl: control and test-bench software for a horizontal vibratory rod mill.

The physics comes from the paper in ``shared/paper/rod-mill-paper.txt``; the
interlock that keeps the mill inside the eq. 9 detachment envelope lives in
:mod:`millctl.safety`.
"""

from importlib.metadata import PackageNotFoundError, version
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from millctl.client import AsyncClient, Client

try:
    __version__ = version("millctl")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = ["AsyncClient", "Client", "__version__"]


def __getattr__(name: str) -> Any:
    """``millctl.Client`` and ``millctl.AsyncClient``, imported on first use (keeps ``import millctl`` light)."""
    if name in ("Client", "AsyncClient"):
        from millctl import client

        return getattr(client, name)
    raise AttributeError(f"module 'millctl' has no attribute {name!r}")

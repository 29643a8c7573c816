"""The controller service (``millctl serve``): the control loop, its local HTTP API, records and the lease.

See docs/operations.md, "The controller service". Clients use :mod:`millctl.client`.
"""

from millctl.service.app import create_app
from millctl.service.lease import DEFAULT_TTL_S, Lease, LeaseError, LeaseManager
from millctl.service.runtime import NodeUnreachable, ServiceRuntime
from millctl.service.server import ServiceRunning, serve

__all__ = [
    "DEFAULT_TTL_S",
    "Lease",
    "LeaseError",
    "LeaseManager",
    "NodeUnreachable",
    "ServiceRunning",
    "ServiceRuntime",
    "create_app",
    "serve",
]

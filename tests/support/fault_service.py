"""``python -m tests.support.fault_service CONFIG``: ``millctl serve`` whose embedded node accepts fault injection.

The service has no switch to enable fault injection on its embedded node
(only ``python -m firmware_sim --fault-injection`` has one), and its virtual
bus exists only inside its own process. So this helper runs the real
:func:`millctl.service.serve` with a runtime whose node has injection
enabled, and injects by signal: SIGUSR1 sends a real SimFault VIB_STALL frame
on the service's bus, SIGUSR2 a CLEAR.
"""

from __future__ import annotations

import signal
import sys
from types import FrameType
from typing import Any

from millctl.config import load_config
from millctl.protocol import SimFault, SimFaultCode, default_codec, open_bus
from millctl.service import server
from millctl.service.runtime import ServiceRuntime


class FaultInjectingRuntime(ServiceRuntime):
    """The service runtime, with the embedded node's fault injection on."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.node.faults.enabled = True


def main(config_path: str) -> int:
    loaded = load_config(config_path)
    bus = open_bus(loaded.config.bus)
    codec = default_codec()

    def inject(fault: SimFaultCode, active: bool) -> Any:
        def handler(signum: int, frame: FrameType | None) -> None:
            bus.send(codec.encode(SimFault(fault, active, 0.0)))

        return handler

    signal.signal(signal.SIGUSR1, inject(SimFaultCode.VIB_STALL, True))
    signal.signal(signal.SIGUSR2, inject(SimFaultCode.CLEAR, False))
    vars(server)["ServiceRuntime"] = FaultInjectingRuntime  # serve() builds its runtime by this name
    try:
        return server.serve(loaded)
    finally:
        bus.shutdown()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))

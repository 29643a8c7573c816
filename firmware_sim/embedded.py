"""The simulated mill a process embeds (``millctl serve`` on the virtual bus): the millbus node or the CiA 402 drives.

Which one follows ``[drives] backend`` (docs/operations.md, "Simulated node";
docs/protocol.md, "CiA 402"); CiA 402 drives with ``furnace = "millbus"`` come
with the furnace-only millbus node on ``[drives.furnace_bus]``. All have
``tick()``, ``close()``, ``faults`` (the fault injector) and ``true_speeds_rpm``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import can

from firmware_sim.node import Node
from millctl.clock import Clock
from millctl.config.models import DriveBackend, FurnaceBackend, MillConfig

if TYPE_CHECKING:
    from firmware_sim.cia402.furnace_mill import Cia402FurnaceMill
    from firmware_sim.cia402.mill import Cia402Mill


def simulated_mill(
    config: MillConfig, bus: can.BusABC, clock: Clock, *, fault_injection: bool
) -> Node | Cia402Mill | Cia402FurnaceMill:
    """The simulated node (millbus) or drives (cia402, and the furnace node) on ``bus``, stepped by the caller."""
    if config.drives.backend is DriveBackend.CIA402 and config.drives.furnace is FurnaceBackend.MILLBUS:
        from firmware_sim.cia402.furnace_mill import Cia402FurnaceMill  # canopen only for this backend

        return Cia402FurnaceMill(config, bus, clock, fault_injection=fault_injection)
    if config.drives.backend is DriveBackend.CIA402:
        from firmware_sim.cia402.mill import Cia402Mill  # canopen only for this backend (issue 36, part 5)

        return Cia402Mill(config, bus, clock, fault_injection=fault_injection)
    return Node(config, bus, clock, fault_injection=fault_injection)


__all__ = ["simulated_mill"]

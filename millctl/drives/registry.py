"""The drive backends by the name ``[drives] backend`` gives them, each imported only when chosen."""

from __future__ import annotations

import can

from millctl.config.models import DriveBackend, MillConfig
from millctl.drives.base import DrivesBackend
from millctl.drives.millbus import MillbusDrives
from millctl.protocol import Codec
from millctl.safety import Envelope


def open_drives(
    config: MillConfig, bus: can.BusABC, codec: Codec, envelope: Envelope, *, furnace_bus: can.BusABC | None = None
) -> DrivesBackend:
    """The configured backend on ``bus`` (CiA 402 imports python-canopen only here).

    ``furnace_bus``: the furnace node's channel beside CiA 402 drives, opened by the caller (the service taps it
    for its bus log) and shut down by it; None: the backend opens ``[drives.furnace_bus]`` itself when configured.
    """
    if config.drives.backend is DriveBackend.CIA402:
        from millctl.drives.cia402 import Cia402Drives

        return Cia402Drives(config, bus, envelope, codec=codec, furnace_bus=furnace_bus)
    if furnace_bus is not None:
        raise ValueError("a furnace channel of its own is for CiA 402 drives only ([drives.furnace_bus])")
    return MillbusDrives(bus, codec)


__all__ = ["open_drives"]

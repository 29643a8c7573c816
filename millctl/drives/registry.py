"""The drive backends by the name ``[drives] backend`` gives them, each imported only when chosen."""

from __future__ import annotations

import can

from millctl.config.models import DriveBackend, MillConfig
from millctl.drives.base import DrivesBackend
from millctl.drives.millbus import MillbusDrives
from millctl.protocol import Codec
from millctl.safety import Envelope


def open_drives(config: MillConfig, bus: can.BusABC, codec: Codec, envelope: Envelope) -> DrivesBackend:
    """The configured backend on ``bus`` (CiA 402 imports python-canopen only here; it opens the furnace's bus)."""
    if config.drives.backend is DriveBackend.CIA402:
        from millctl.drives.cia402 import Cia402Drives

        return Cia402Drives(config, bus, envelope, codec=codec)
    return MillbusDrives(bus, codec)


__all__ = ["open_drives"]

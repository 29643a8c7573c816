"""Simulated CiA 402 drives (issue 36): canopen LocalNodes with the millbus node's drive dynamics and faults.

:class:`Cia402Mill` is both drives on one bus, stepped by its ``tick()``;
:class:`SimDrive` one drive; :mod:`.power` the drive-side power state machine.
docs/protocol.md, "CiA 402".
"""

from firmware_sim.cia402.drive import SimDrive
from firmware_sim.cia402.mill import Cia402Mill, eds_path
from firmware_sim.cia402.power import PowerState

__all__ = ["Cia402Mill", "PowerState", "SimDrive", "eds_path"]

"""Standard CANopen CiA 402 drives, one per motor, behind the drives boundary (issue 36; docs/protocol.md#cia-402)."""

from millctl.drives.cia402.backend import Cia402Drives
from millctl.drives.cia402.state402 import Controlword, Power, PowerMachine, decode_statusword

__all__ = ["Cia402Drives", "Controlword", "Power", "PowerMachine", "decode_statusword"]

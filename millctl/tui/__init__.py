"""The operator terminal UI (``millctl tui``), a textual client of the controller service."""

from millctl.tui.app import MillApp
from millctl.tui.sim import SimService

__all__ = ["MillApp", "SimService"]

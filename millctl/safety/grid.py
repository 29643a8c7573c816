"""The speeds each axis can carry on the wire: the grid the planner snaps to, so that the interlock checks what is sent.

A setpoint goes on the wire as a whole number of counts, and the receiver
reads the count back as a speed. The interlock must check exactly that read
value, not the controller's float (SAFETY 21): the planner snaps every
setpoint onto this grid before the envelope sees it, and each grid's
:meth:`AxisGrid.snap` computes the value the way the receiver computes it.

* millbus (:class:`ScaledGrid`): count × 0.1 rpm, the DBC's factor, as the
  node's decoder multiplies it (``config/millbus.dbc``).
* a CiA 402 drive (:class:`DriveGrid`): count / (gear_ratio × units_per_rpm),
  as :meth:`millctl.config.models.Cia402Drive.mill_rpm` reads a velocity. A
  drive whose unit is coarser than the millbus grid (e.g. units_per_rpm = 0.1:
  one unit = 10 mill rpm) is snapped to its own unit; a finer one to the
  fewest whole units that span at least the millbus grid, so the grid stays a
  whole number of drive units (the round trip is exact) and no finer than the
  0.1 rpm that statuses, records and recipes show (and the wire check of
  :mod:`millctl.safety.wire` enumerates).
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass
from typing import overload

import numpy as np
from numpy.typing import NDArray

from millctl.config.models import DriveBackend, MillConfig

MILLBUS_RESOLUTION_RPM = 0.1
"""The millbus wire's speed resolution (rpm; ``config/millbus.dbc``, factor 0.1)."""

_FLOOR_SLACK = 1e-9
"""Relative slack of :meth:`AxisGrid.floor`, so that a grid value computed in floats floors onto itself."""


class AxisGrid(abc.ABC):
    """One axis's wire grid: the values ``value(k)`` for integer k, ``step_rpm`` apart."""

    @property
    @abc.abstractmethod
    def step_rpm(self) -> float:
        """The distance between neighbouring grid values (rpm)."""

    @overload
    def snap(self, value_rpm: float) -> float: ...

    @overload
    def snap(self, value_rpm: NDArray[np.float64]) -> NDArray[np.float64]: ...

    def snap(self, value_rpm: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
        """The nearest grid value, computed as the receiver reads it (rpm; arrays element-wise)."""
        counts = np.round(np.asarray(value_rpm, dtype=float) / self.step_rpm)
        snapped = self._value(counts)
        return float(snapped) if np.ndim(snapped) == 0 else np.asarray(snapped, dtype=float)

    def floor(self, value_rpm: float) -> float:
        """The highest grid value at or below ``value_rpm`` (rpm; ≥ 0)."""
        counts = math.floor(value_rpm / self.step_rpm + _FLOOR_SLACK)
        return max(0.0, float(self._value(np.float64(counts))))

    @abc.abstractmethod
    def _value(self, counts: NDArray[np.float64] | np.float64) -> NDArray[np.float64] | np.float64:
        """The speed ``counts`` stand for, computed as the receiver computes it (rpm)."""


@dataclass(frozen=True)
class ScaledGrid(AxisGrid):
    """A grid of count × ``resolution_rpm`` (the millbus DBC's linear factor)."""

    resolution_rpm: float = MILLBUS_RESOLUTION_RPM

    def __post_init__(self) -> None:
        if not (math.isfinite(self.resolution_rpm) and self.resolution_rpm > 0.0):
            raise ValueError(f"resolution_rpm = {self.resolution_rpm} must be > 0")

    @property
    def step_rpm(self) -> float:
        """The resolution (rpm)."""
        return self.resolution_rpm

    def _value(self, counts: NDArray[np.float64] | np.float64) -> NDArray[np.float64] | np.float64:
        return counts * self.resolution_rpm


@dataclass(frozen=True)
class DriveGrid(AxisGrid):
    """A grid of whole multiples of ``stride`` drive units, read as count / ``units_per_mill_rpm``."""

    units_per_mill_rpm: float
    """Drive velocity units per mill rpm: gear_ratio × units_per_rpm (:attr:`Cia402Drive.units_per_mill_rpm`)."""
    stride: int = 1
    """Drive units a grid step spans."""

    @classmethod
    def for_drive(cls, units_per_mill_rpm: float, finest_rpm: float = MILLBUS_RESOLUTION_RPM) -> DriveGrid:
        """The drive's own unit, or the fewest whole units that span ``finest_rpm`` where the unit is finer."""
        stride = max(1, math.ceil(finest_rpm * units_per_mill_rpm - _FLOOR_SLACK))
        return cls(units_per_mill_rpm, stride)

    @property
    def step_rpm(self) -> float:
        """``stride`` drive units in mill rpm."""
        return self.stride / self.units_per_mill_rpm

    def _value(self, counts: NDArray[np.float64] | np.float64) -> NDArray[np.float64] | np.float64:
        # (count × stride) is a whole number of drive units, divided as Cia402Drive.mill_rpm divides it
        return (counts * self.stride) / self.units_per_mill_rpm


def wire_grids(config: MillConfig) -> tuple[AxisGrid, AxisGrid]:
    """The (rotary, vibration) grids of the configured backend's wire (docs/safety.md, SAFETY 21)."""
    drives = config.drives
    if drives.backend is DriveBackend.CIA402:
        grids = []
        for drive in (drives.rotary, drives.vibration):
            assert drive.cia402 is not None  # the config's validator requires it with backend = "cia402"
            grids.append(DriveGrid.for_drive(drive.cia402.units_per_mill_rpm))
        return grids[0], grids[1]
    return ScaledGrid(), ScaledGrid()


__all__ = ["MILLBUS_RESOLUTION_RPM", "AxisGrid", "DriveGrid", "ScaledGrid", "wire_grids"]

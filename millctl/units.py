"""Unit conversions at the edges: rpm ↔ rad/s, degrees ↔ radians, °C ↔ K."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, TypeVar

if TYPE_CHECKING:  # numpy only names the array type here: a float conversion loads no numpy (CLI start-up)
    import numpy as np
    from numpy.typing import NDArray

ArrayOrFloat = TypeVar("ArrayOrFloat", float, "NDArray[np.float64]")

RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)
"""Revolutions per minute in one radian per second."""


def rpm_to_rad_s(speed_rpm: ArrayOrFloat) -> ArrayOrFloat:
    """Angular speed: rpm → rad/s."""
    return speed_rpm / RPM_PER_RAD_S


def rad_s_to_rpm(speed_rad_s: ArrayOrFloat) -> ArrayOrFloat:
    """Angular speed: rad/s → rpm."""
    return speed_rad_s * RPM_PER_RAD_S


def celsius_to_kelvin(temp_c: float) -> float:
    """Temperature: °C → K."""
    return temp_c + 273.15


__all__ = ["RPM_PER_RAD_S", "celsius_to_kelvin", "rad_s_to_rpm", "rpm_to_rad_s"]

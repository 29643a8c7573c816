"""The ``[drives]`` section: the two motor drives, and the backend they are driven through (millbus or CiA 402).

Split from :mod:`millctl.config.models` (which re-exports every name here);
the CiA 402 parts are checked when read: node IDs in 1–127 and distinct,
scalings finite and > 0, an EDS that exists and parses
(docs/deployment.md#standard-cia-402-drives); a furnace beside them
(``furnace = "millbus"``) needs its own channel, ``[drives.furnace_bus]``,
which is not the drives' ``[bus]`` (docs/deployment.md, "A furnace beside the
drives: a second CAN channel").
"""

from __future__ import annotations

import enum
import math
from pathlib import Path
from typing import Annotated

from pydantic import AfterValidator, Field, field_validator, model_validator

from millctl.config.base import StrictModel as _Strict
from millctl.config.bus import Bus

FURNACE_DOCS = "docs/deployment.md#a-furnace-beside-the-drives-a-second-can-channel"


class DriveBackend(enum.StrEnum):
    """What the controller drives the motors through (``[drives] backend``; docs/deployment.md)."""

    MILLBUS = "millbus"
    """The millbus node (``config/millbus.dbc``): drives and furnace behind one custom node."""
    CIA402 = "cia402"
    """Two standard CANopen CiA 402 drives, one per motor (docs/deployment.md#standard-cia-402-drives)."""


class Cia402Mode(enum.StrEnum):
    """The CiA 402 mode of operation a drive runs in (object 0x6060)."""

    PROFILE_VELOCITY = "profile-velocity"
    """0x6060 = 3: target 0x60FF (i32), actual 0x606C (i32)."""
    VELOCITY = "velocity"
    """0x6060 = 2: target 0x6042 (i16), actual 0x6044 (i16)."""


class FurnaceBackend(enum.StrEnum):
    """Where the furnace is on a CiA 402 mill: the millbus furnace node, or none (cold milling)."""

    MILLBUS = "millbus"
    """The millbus node in its furnace-only mode, on a CAN channel of its own (``[drives.furnace_bus]``)."""
    NONE = "none"
    """No furnace: cold milling."""


SCALING_MAX = 1e9
"""Largest velocity scaling factor accepted (a drive unit per rpm, or a gear ratio)."""


def _scaling(value: float) -> float:
    if not (math.isfinite(value) and 0.0 < value <= SCALING_MAX):
        raise ValueError(
            f"{value} is not a usable scaling: it must be a finite number > 0 (bound: 0 < value ≤ {SCALING_MAX:g}); "
            "wire value = round(mill rpm × gear_ratio × units_per_rpm) (docs/deployment.md#standard-cia-402-drives)"
        )
    return value


_Finite = Annotated[float, AfterValidator(_scaling)]


def _node_id_in_range(value: int) -> int:
    if not 1 <= value <= 127:
        raise ValueError(
            f"CANopen node ID {value} is outside 1–127 (bound: 1 ≤ node_id ≤ 127; 0 addresses every node, "
            "128 and up do not exist; docs/deployment.md#standard-cia-402-drives)"
        )
    return value


_NodeId = Annotated[int, AfterValidator(_node_id_in_range)]


class Cia402Drive(_Strict):
    """One CiA 402 drive on the bus: its node ID, its object dictionary, its velocity scaling and mode.

    Wire value = round(mill rpm × ``gear_ratio`` × ``units_per_rpm``).
    """

    node_id: _NodeId
    """CANopen node ID (1–127), distinct from the other drive's and the controller's."""
    eds: str = ""
    """The drive's EDS file ("" = the shipped generic ``cia402-drive.eds``; relative to the config file)."""
    units_per_rpm: _Finite = 1.0
    """Drive velocity units per motor rpm (finite, > 0)."""
    gear_ratio: _Finite = 1.0
    """Motor rpm per mill rpm (finite, > 0)."""
    mode: Cia402Mode = Cia402Mode.PROFILE_VELOCITY

    @field_validator("eds")
    @classmethod
    def _eds_exists(cls, value: str) -> str:
        if not value:
            return value
        if not Path(value).is_file():
            raise ValueError(
                f"EDS file {value!r} not found (a path relative to the config file, or \"\" for the shipped "
                "generic cia402-drive.eds; docs/deployment.md#standard-cia-402-drives)"
            )
        import canopen  # only a CiA 402 configuration needs it

        try:
            canopen.import_od(value)
        except Exception as exc:  # the EDS parser raises whatever it meets in a file that is not one
            shown = " ".join(str(exc).split())
            raise ValueError(f"EDS file {value!r} is not a readable EDS ({type(exc).__name__}: {shown})") from None
        return value

    @property
    def units_per_mill_rpm(self) -> float:
        """Drive velocity units per mill rpm: gear_ratio × units_per_rpm (the planner's grid, SAFETY 21)."""
        return self.gear_ratio * self.units_per_rpm

    def wire_velocity(self, mill_rpm: float) -> int:
        """The drive's target velocity for a mill speed (rpm → drive units, rounded).

        The controller sends only speeds the planner snapped onto this drive's
        grid (:mod:`millctl.safety.grid`), for which the rounding is exact.
        """
        return round(mill_rpm * self.units_per_mill_rpm)

    def mill_rpm(self, wire_velocity: int) -> float:
        """The mill speed a drive velocity (drive units) stands for (rpm)."""
        return wire_velocity / self.units_per_mill_rpm


class Drive(_Strict):
    """One motor drive: absolute limits and first-order speed dynamics."""

    max_speed_rpm: Annotated[float, Field(gt=0.0, le=10_000.0)]
    max_accel_rpm_s: Annotated[float, Field(gt=0.0, le=10_000.0)]
    time_constant_s: Annotated[float, Field(gt=0.0, le=60.0)] = 0.2
    speed_noise_rpm: Annotated[float, Field(ge=0.0, le=100.0)] = 0.5
    """Standard deviation of the measured-speed noise (rpm)."""
    rated_torque_nm: Annotated[float, Field(gt=0.0, le=1_000.0)] = 2.0
    cia402: Cia402Drive | None = None
    """The motor's CiA 402 drive (used with ``[drives] backend = "cia402"``)."""


class Drives(_Strict):
    """The two drives of the mill, and what they are driven through."""

    backend: DriveBackend = DriveBackend.MILLBUS
    rotary: Drive
    vibration: Drive
    controller_node_id: _NodeId = 1
    """The controller's CANopen node ID (CiA 402 backend): its heartbeat is sent at 0x700 + this."""
    furnace: FurnaceBackend = FurnaceBackend.NONE
    """CiA 402 backend: the furnace beside the drives, "millbus" (its own channel) or "none" (cold milling)."""
    furnace_bus: Bus | None = None
    """CiA 402 backend with ``furnace = "millbus"``: the CAN channel of the millbus furnace node (not the drives')."""

    @model_validator(mode="after")
    def _cia402_complete(self) -> Drives:
        self._furnace_channel()
        if self.backend is not DriveBackend.CIA402:
            return self
        ids: dict[int, str] = {self.controller_node_id: "drives.controller_node_id"}
        for motor in ("rotary", "vibration"):
            drive: Drive = getattr(self, motor)
            if drive.cia402 is None:
                raise ValueError(
                    f"backend = \"cia402\" needs [drives.{motor}.cia402] with node_id (1–127) "
                    "(docs/deployment.md#standard-cia-402-drives)"
                )
            node_id = drive.cia402.node_id
            if node_id in ids:
                raise ValueError(
                    f"drives.{motor}.cia402.node_id = {node_id} is already {ids[node_id]}: each CANopen node "
                    "needs its own ID (1–127)"
                )
            ids[node_id] = f"drives.{motor}.cia402.node_id"
        return self

    def _furnace_channel(self) -> None:
        """``furnace`` and ``[drives.furnace_bus]`` agree with the backend (each refusal names the field)."""
        if self.furnace_bus is not None and (self.backend is not DriveBackend.CIA402
                                             or self.furnace is not FurnaceBackend.MILLBUS):
            raise ValueError(
                "[drives.furnace_bus] is given but the furnace has no channel of its own here (it needs "
                "backend = \"cia402\" and furnace = \"millbus\"; with backend = \"millbus\" the furnace is "
                f"the millbus node's, with furnace = \"none\" there is none): drop the section ({FURNACE_DOCS})"
            )
        if self.backend is DriveBackend.CIA402 and self.furnace is FurnaceBackend.MILLBUS and self.furnace_bus is None:
            raise ValueError(
                "drives.furnace = \"millbus\" beside CiA 402 drives needs [drives.furnace_bus] with the furnace "
                "node's own interface and channel: the millbus node cannot share the drives' bus (its E-stop "
                f"0x000 is CANopen's NMT, its NodeStatus 0x100 the TIME object; {FURNACE_DOCS})"
            )

    def check_channels(self, drives_bus: Bus) -> None:
        """Refuse a furnace channel that is the drives' own (``[bus]``): the identifiers would clash there."""
        furnace = self.furnace_bus
        if furnace is None:
            return
        same_port = furnace.options.get("port") == drives_bus.options.get("port")
        if furnace.interface == drives_bus.interface and furnace.channel == drives_bus.channel and same_port:
            raise ValueError(
                f"drives.furnace_bus.channel = {furnace.channel!r} on {furnace.interface} is the drives' own "
                f"bus ([bus]): the furnace node needs a second CAN channel ({FURNACE_DOCS})"
            )


__all__ = [
    "SCALING_MAX",
    "Cia402Drive",
    "Cia402Mode",
    "Drive",
    "DriveBackend",
    "Drives",
    "FurnaceBackend",
]

"""The limits each CiA 402 drive is given by SDO before every move: the second channel of the interlock (SAFETY 28).

The envelope (:mod:`millctl.safety.envelope`) stays the one decider; these
values put its bounds into the drives, so a drive holds them whatever the
controller sends afterwards: 0x607F max profile velocity and 0x6080 max motor
speed from the absolute caps (the rotary drive's 0x607F also from the eq. 9
limit at the lowest ω_v the move passes through), 0x6083/0x6084 profile
acceleration/deceleration and 0x6085 quick-stop deceleration from the
drive's ``max_accel_rpm_s``, and 0x605A the quick-stop option code. The speed
caps are rounded down onto the drive's grid (a cap rounded up would admit up
to a unit above the envelope, SAFETY 21); the rates are rounded up (a rate
rounded down would make the drive lag the planned ramp).
Each is written, then read back; a drive whose read-back differs is not
enabled and the move is refused naming the object (:func:`mismatch`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from millctl.config.models import Cia402Drive, Drive
from millctl.drives.cia402.state402 import QUICK_STOP_OPTION
from millctl.safety import Envelope, Trajectory


@dataclass(frozen=True)
class LimitObject:
    """One object written to a drive: index, subindex, value (drive units), and what it is."""

    index: int
    subindex: int
    value: int
    name: str

    @property
    def where(self) -> str:
        """The object as CiA 402 names it: ``0x607F:00 max profile velocity``."""
        return f"0x{self.index:04X}:{self.subindex:02X} {self.name}"


def _floor_units(mill_rpm: float, cia: Cia402Drive) -> int:
    """A speed cap (mill rpm) as the most drive velocity units whose mill speed does not exceed it (SAFETY 21).

    Rounded down, never up: a cap written rounded up would let the drive run
    up to a unit above the envelope. Every speed the controller commands is
    on the drive's grid (:mod:`millctl.safety.grid`), so a cap that is one
    such speed floors onto itself and never clips it. Judged by the drive's
    own read-back conversion (:meth:`Cia402Drive.mill_rpm`), not a float
    tolerance.
    """
    units = max(math.floor(mill_rpm * cia.units_per_mill_rpm), 0)
    while cia.mill_rpm(units + 1) <= mill_rpm:
        units += 1
    while units > 0 and cia.mill_rpm(units) > mill_rpm:
        units -= 1
    return units


def _floor_motor_rpm(mill_rpm: float, cia: Cia402Drive) -> int:
    """A speed cap (mill rpm) as the most whole motor rpm (0x6080's unit) that do not exceed it."""
    motor_rpm = max(math.floor(mill_rpm * cia.gear_ratio), 0)
    while (motor_rpm + 1) / cia.gear_ratio <= mill_rpm:
        motor_rpm += 1
    while motor_rpm > 0 and motor_rpm / cia.gear_ratio > mill_rpm:
        motor_rpm -= 1
    return motor_rpm


def _ceil_units(rate_rpm_s: float, cia: Cia402Drive) -> int:
    """An acceleration (mill rpm/s) as drive units, rounded up: the drive must follow every ramp the planner plans."""
    return max(math.ceil(rate_rpm_s * cia.units_per_mill_rpm - 1e-9), 0)


def lowest_vibration_rpm(move: Trajectory | None) -> float:
    """The lowest ω_v (rpm) a move passes through (0 for arming at standstill); segments are linear."""
    if move is None:
        return 0.0
    points = [move.start, move.end, *(move.at(seg.t1_s) for seg in move.segments)]
    return min(abs(p.omega_v_rpm) for p in points)


def highest_rotary_rpm(move: Trajectory | None) -> float:
    """The highest |ω_r| (rpm) a move commands (0 for arming at standstill)."""
    if move is None:
        return 0.0
    points = [move.start, move.end, *(move.at(seg.t1_s) for seg in move.segments)]
    return max(abs(p.omega_r_rpm) for p in points)


def drive_limits(
    motor: str, drive: Drive, cia: Cia402Drive, envelope: Envelope, move: Trajectory | None
) -> list[LimitObject]:
    """The objects written to one drive before ``move`` (None: before enabling at standstill)."""
    cap_rpm = drive.max_speed_rpm
    if motor == "rotary":  # eq. 9 at the lowest ω_v, never below what the (checked) move itself commands
        eq9_rpm = envelope.limit_rpm(lowest_vibration_rpm(move))
        cap_rpm = min(cap_rpm, max(eq9_rpm, highest_rotary_rpm(move)))
    accel = _ceil_units(drive.max_accel_rpm_s, cia)
    # both caps rounded down onto the drive's grid: a written limit never admits more than the envelope
    return [
        LimitObject(0x607F, 0, _floor_units(cap_rpm, cia), "max profile velocity"),
        LimitObject(0x6080, 0, _floor_motor_rpm(drive.max_speed_rpm, cia), "max motor speed"),
        LimitObject(0x6083, 0, accel, "profile acceleration"),
        LimitObject(0x6084, 0, accel, "profile deceleration"),
        LimitObject(0x6085, 0, accel, "quick stop deceleration"),
        LimitObject(0x605A, 0, QUICK_STOP_OPTION, "quick stop option code"),
    ]


def mismatch(motor: str, node_id: int, limit: LimitObject, read_back: int | None) -> str:
    """The refusal for one object whose read-back differs from what was written (None: no answer)."""
    got = "no answer" if read_back is None else f"read back {read_back}"
    return (
        f"{motor} drive (node {node_id}): {limit.where} written {limit.value}, {got}: the drive does not hold "
        "the limit, it is not enabled (docs/safety.md#cia-402-drives)"
    )


__all__ = ["LimitObject", "drive_limits", "highest_rotary_rpm", "lowest_vibration_rpm", "mismatch"]

"""The two simulated drives: speed loop, limits, load torque from the rod charge, speed sensor.

Each drive is a speed-controlled motor. Its speed loop is modelled as a first
order lag behind the commanded speed, slew-limited by the drive's maximum
acceleration and bounded by its absolute maximum speed (the drive's own
firmware limit). The node keeps a second, fault-free copy of the same model
as its *reference*: what the drive should be doing for the commands it was
given. The plausibility checks (:mod:`firmware_sim.monitor`) compare the
measured speed with it.

Faults injected here (:mod:`firmware_sim.faults`) act on the true speed
(stall, runaway) or only on the sensor (stuck, noisy).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from millctl.config.models import G_M_S2, Drive, MillConfig

STANDSTILL_SNAP_RPM = 0.01
"""Below this true speed with a zero command the rotor is at rest (rpm); encoders then read exactly 0."""


@dataclass(frozen=True)
class ChargeLoad:
    """The rod charge as the drives feel it (a deliberately simple, documented model).

    Rotary drive: the vial wall drags the n rods (mass m each, centres on the
    circle r0 = r_v − r_r) up until friction balances gravity, so the charge's
    centre of mass sits displaced from bottom dead centre by the friction angle
    φ = atan μ. Holding it there takes the torque n·m·g·r0·sin φ while the vial
    turns (zero at standstill). Accelerating the charge takes n·m·r0²·dω/dt.

    Vibration drive: the cam lifts the vial platform with the charge by 2·r_d
    per cam revolution; the mean torque of lifting a weight W through a cam of
    eccentricity r_d is W·r_d·2/π (the mean of |sin|), the spring's work
    averaging to zero over a revolution.
    """

    rotary_friction_torque_nm: float
    """n·m·g·r0·sin(atan μ) (N·m)."""
    rotary_inertia_kg_m2: float
    """n·m·r0² (kg·m²)."""
    vibration_lift_torque_nm: float
    """n·m·g·r_d·2/π (N·m)."""

    @classmethod
    def from_config(cls, config: MillConfig) -> ChargeLoad:
        """The charge of the configured mill (rods' mass, r0, cam eccentricity, powder friction μ)."""
        mill = config.mill
        charge_kg = mill.rods.count * config.rod_mass_kg
        r0_m = mill.vial.radius_m - mill.rods.radius_m
        friction_angle = math.atan(config.model.powder_friction)
        return cls(
            rotary_friction_torque_nm=charge_kg * G_M_S2 * r0_m * math.sin(friction_angle),
            rotary_inertia_kg_m2=charge_kg * r0_m**2,
            vibration_lift_torque_nm=charge_kg * G_M_S2 * mill.cam.eccentricity_m * 2.0 / math.pi,
        )


class DriveModel:
    """One drive's true speed (rpm), its torque (N·m) and its speed sensor."""

    def __init__(self, drive: Drive, rng: np.random.Generator) -> None:
        self.drive = drive
        self._rng = rng
        self.speed_rpm = 0.0
        """True rotor speed (rpm), never negative (the drives turn one way)."""
        self.accel_rpm_s = 0.0
        """Acceleration over the last step (rpm/s)."""
        self.stalled = False
        """Injected: the rotor is blocked and coasts to rest whatever the command."""
        self.runaway_rpm: float | None = None
        """Injected: the speed loop ignores the command and drives towards this speed (rpm)."""
        self.sensor_stuck_rpm: float | None = None
        """Injected: the sensor reads this value whatever the rotor does (rpm)."""
        self.sensor_noise_rpm: float | None = None
        """Injected: the sensor's noise standard deviation (rpm) instead of the configured one."""
        self.measured_rpm = 0.0
        """The last sensor reading (rpm)."""

    def step(self, command_rpm: float, dt_s: float) -> None:
        """Advance the rotor by ``dt_s`` seconds towards ``command_rpm``."""
        if dt_s <= 0.0:
            return
        drive = self.drive
        before = self.speed_rpm
        if self.stalled:
            # A blocked rotor (seized bearing, jammed cam): the drive cannot turn it, and its speed decays to rest
            # at the drive's deceleration limit whatever the command.
            target, slew = 0.0, drive.max_accel_rpm_s
        elif self.runaway_rpm is not None:
            # A runaway speed loop (e.g. a lost encoder on the drive side): full torque towards the fault speed,
            # past the drive's configured limit.
            target, slew = self.runaway_rpm, drive.max_accel_rpm_s
        else:
            target, slew = min(max(command_rpm, 0.0), drive.max_speed_rpm), drive.max_accel_rpm_s
        # First-order lag dω/dt = (ω_cmd − ω)/τ, integrated exactly over dt (stable for any dt) ...
        lagged = target + (before - target) * math.exp(-dt_s / drive.time_constant_s)
        # ... then the drive's slew limit |dω/dt| ≤ max_accel.
        max_step = slew * dt_s
        after = before + min(max(lagged - before, -max_step), max_step)
        if target == 0.0 and after < STANDSTILL_SNAP_RPM:
            after = 0.0
        self.speed_rpm = max(after, 0.0)
        self.accel_rpm_s = (self.speed_rpm - before) / dt_s

    def sample(self) -> float:
        """Read the speed sensor (rpm): the true speed plus seeded Gaussian noise, never negative.

        A speed sensor counts pulses, so a rotor at rest reads exactly 0 and a
        turning one never reads below 0.
        """
        if self.sensor_stuck_rpm is not None:
            self.measured_rpm = self.sensor_stuck_rpm
            return self.measured_rpm
        noise = self.drive.speed_noise_rpm if self.sensor_noise_rpm is None else self.sensor_noise_rpm
        if self.speed_rpm == 0.0 and self.sensor_noise_rpm is None:
            self.measured_rpm = 0.0
        elif noise > 0.0:
            self.measured_rpm = max(0.0, self.speed_rpm + float(self._rng.normal(0.0, noise)))
        else:
            self.measured_rpm = self.speed_rpm
        return self.measured_rpm

    def torque_nm(self, load_nm: float, inertia_kg_m2: float) -> float:
        """Motor torque (N·m): the load while turning plus the charge's inertia times the acceleration.

        A stalled or runaway drive is at its torque limit, the rated torque.
        """
        if self.stalled or self.runaway_rpm is not None:
            return self.drive.rated_torque_nm
        turning = 1.0 if self.speed_rpm > 0.0 else 0.0
        accel_rad_s2 = self.accel_rpm_s * 2.0 * math.pi / 60.0
        return turning * load_nm + inertia_kg_m2 * accel_rad_s2


class DrivePair:
    """Both drives, their fault-free reference copies, and the charge load."""

    def __init__(self, config: MillConfig, rng: np.random.Generator) -> None:
        self.rotary = DriveModel(config.drives.rotary, rng)
        self.vibration = DriveModel(config.drives.vibration, rng)
        reference_rng = np.random.default_rng(0)
        self.rotary_ref = DriveModel(config.drives.rotary, reference_rng)
        self.vibration_ref = DriveModel(config.drives.vibration, reference_rng)
        self.load = ChargeLoad.from_config(config)
        self._max_step_s = config.timing.node_tick_s

    def step(self, rotary_cmd_rpm: float, vibration_cmd_rpm: float, dt_s: float) -> None:
        """Advance the drives and their references by ``dt_s`` (sub-stepped at the node tick)."""
        steps = max(1, math.ceil(dt_s / self._max_step_s - 1e-9))
        h = dt_s / steps
        for _ in range(steps):
            self.rotary.step(rotary_cmd_rpm, h)
            self.vibration.step(vibration_cmd_rpm, h)
            self.rotary_ref.step(rotary_cmd_rpm, h)
            self.vibration_ref.step(vibration_cmd_rpm, h)

    def sample(self) -> tuple[float, float]:
        """Read both speed sensors: (ω_r, ω_v) measured (rpm)."""
        return self.rotary.sample(), self.vibration.sample()

    def torques_nm(self) -> tuple[float, float]:
        """Motor torques (N·m) of the rotary and the vibration drive."""
        return (
            self.rotary.torque_nm(self.load.rotary_friction_torque_nm, self.load.rotary_inertia_kg_m2),
            self.vibration.torque_nm(self.load.vibration_lift_torque_nm, 0.0),
        )


__all__ = ["STANDSTILL_SNAP_RPM", "ChargeLoad", "DriveModel", "DrivePair"]

"""Pydantic models of the mill configuration (``config/mill.toml``).

Every field carries its unit in its name and a bound; unknown keys are
rejected. SI quantities for the physics are derived properties (``*_m``,
``*_kg``, ``*_rad_s``) so that the file can speak the lab's units (mm, rpm,
°C) while the code computes in SI. The ``[drives]`` section lives in
:mod:`millctl.config.drives`, and its names are re-exported here.
"""

from __future__ import annotations

import enum
import math
from typing import Annotated

from pydantic import Field, field_validator, model_validator

from millctl.config.base import StrictModel as _Strict
from millctl.config.bus import Bus
from millctl.config.drives import Cia402Drive, Cia402Mode, Drive, DriveBackend, Drives, FurnaceBackend
from millctl.units import rpm_to_rad_s

G_M_S2 = 9.80665
"""Standard gravity (m/s²)."""


class LimitLaw(enum.StrEnum):
    """The detachment limit that bounds the rotary speed (see docs/model.md)."""

    PAPER_EQ9 = "paper-eq9"
    """Printed eq. 9: the paper's bound with sin α = −1 (the paper's recommended default)."""
    PAPER_EVERY_CYCLE = "paper-every-cycle"
    """The paper's eq. 7 at its true worst phase, chosen by the sign of k − mω_v²."""
    CORRECTED_EVERY_PHASE = "corrected-every-phase"
    """Corrected physics, detachment at every cam phase: √(g(1 − Γ)/r0)."""
    CORRECTED_BEST_PHASE = "corrected-best-phase"
    """Corrected physics, detachment at the most favourable cam phase: √(g(1 + Γ)/r0)."""


class ModelVariant(enum.StrEnum):
    """Which physics the simulation runs: the paper as printed, or corrected (docs/model.md)."""

    PAPER = "paper"
    CORRECTED = "corrected"


class CamShape(enum.StrEnum):
    """The vibration cam's shape (docs/model.md#cam-shapes, :mod:`millctl.physics.cam`)."""

    SINGLE = "single"
    """The paper's circular eccentric: one lift stroke per cam revolution, r_d sin α."""
    DOUBLE = "double"
    """The paper's proposed elliptical double-acting cam: two strokes per revolution, r_d sin 2α."""


class Material(_Strict):
    """Elastic and mass properties of a rod or vial material."""

    density_kg_m3: Annotated[float, Field(gt=500.0, le=25_000.0)]
    youngs_modulus_gpa: Annotated[float, Field(gt=1.0, le=1_500.0)]
    poisson_ratio: Annotated[float, Field(ge=0.0, lt=0.5)]
    note: str = ""

    @property
    def youngs_modulus_pa(self) -> float:
        """Young's modulus (Pa)."""
        return self.youngs_modulus_gpa * 1e9


class Rods(_Strict):
    """The milling rods (all equal)."""

    material: str = "steel"
    radius_mm: Annotated[float, Field(gt=0.0, le=100.0)]
    length_mm: Annotated[float, Field(gt=0.0, le=2_000.0)]
    count: Annotated[int, Field(ge=1, le=64)]

    @property
    def radius_m(self) -> float:
        """Rod radius r_r (m)."""
        return self.radius_mm * 1e-3

    @property
    def length_m(self) -> float:
        """Rod length L (m)."""
        return self.length_mm * 1e-3


class Vial(_Strict):
    """The vial (a cylindrical bore)."""

    material: str = "steel"
    radius_mm: Annotated[float, Field(gt=0.0, le=500.0)]

    @property
    def radius_m(self) -> float:
        """Vial radius r_v (m)."""
        return self.radius_mm * 1e-3


class Cam(_Strict):
    """The vibration cam and its geometry."""

    eccentricity_mm: Annotated[float, Field(ge=0.0, le=50.0)]
    """Cam eccentricity r_d, the vibration amplitude (mm)."""
    cam_to_vial_m: Annotated[float, Field(gt=0.0, le=5.0)]
    """Distance l from the cam centre to the vial centre at its highest point (m)."""
    shape: CamShape = CamShape.SINGLE
    """Circular single-acting (the paper's mill) or elliptical double-acting (its proposal)."""

    @property
    def eccentricity_m(self) -> float:
        """Cam eccentricity r_d (m)."""
        return self.eccentricity_mm * 1e-3


class Powder(_Strict):
    """The powder charge in the vial (for the specific energy dose, J per g)."""

    charge_g: Annotated[float, Field(gt=0.0, le=10_000.0)] = 20.0


class Spring(_Strict):
    """The spring term k of the paper's eqs 4–9: a per-rod effective stiffness, not the platform springs' rate.

    The paper puts a spring force k z on one rod (eq. 4), so k is the share of the four platform
    springs that acts on one rod. Only values of the order of m ω_v² (tens to hundreds of N/m; Set A's
    92 N/m gives eq. 9's 200 rpm at ω_v = 800 rpm) make eq. 9 meaningful; a real platform spring rate
    (10⁴–10⁵ N/m) makes eq. 9's numerator m g − (k − m ω_v²) r_d ≤ 0 up to ω_v = √(k/m − g/r_d),
    where the law admits no rotation (``millctl config check`` warns; docs/model.md, errata k).
    """

    stiffness_n_per_m: Annotated[
        float,
        Field(
            ge=0.0,
            le=1e7,
            description="k, per-rod effective stiffness of eqs 4–9 (N/m); not the platform springs' rate",
        ),
    ]


class Model(_Strict):
    """Choices of the physics model (docs/model.md)."""

    variant: ModelVariant = ModelVariant.PAPER
    restitution: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0
    """Coefficient of restitution e of rod impacts; 0 is the paper's plastic impact (eq. 19)."""
    powder_friction: Annotated[float, Field(ge=0.0, le=2.0)] = 0.3
    """Friction coefficient μ between rod or vial and powder (eqs 20, 25)."""


class Structure(_Strict):
    """The vibrating platform's structure, for the structural-load model (docs/model.md#structural-loads).

    The paper gives none of these; the defaults are a stated, light design (docs/model.md names
    them as assumptions), and a study may vary none of them to produce its answer.
    """

    platform_mass_kg: Annotated[float, Field(gt=0.0, le=1_000.0)] = 5.0
    """Vibrating platform without the rods: rotary motor, shaft, bearings, vial holder and vial (kg)."""
    shaft_mass_kg: Annotated[float, Field(gt=0.0, le=1_000.0)] = 1.0
    """The part of it the rotary shaft's bearings carry: vial and holder (kg; rods added separately)."""
    platform_spring_n_per_m: Annotated[float, Field(ge=0.0, le=1e8)] = 1.0e4
    """K_s, the four platform springs together (N/m); not the per-rod k of eqs 4–9."""
    spring_preload_mm: Annotated[float, Field(ge=0.0, le=200.0)] = 0.0
    """δ0, static extension of the platform springs that holds the roller on the cam (mm)."""
    roller_radius_mm: Annotated[float, Field(gt=0.0, le=500.0)] = 10.0
    cam_radius_mm: Annotated[float, Field(gt=0.0, le=1_000.0)] = 30.0
    """Radius of the circular (eccentric) cam disc (mm)."""
    contact_width_mm: Annotated[float, Field(gt=0.0, le=1_000.0)] = 10.0
    """Width of the cam–roller line contact (mm)."""
    contact_endurance_mpa: Annotated[float, Field(gt=0.0, le=10_000.0)] = 1_500.0
    """Endurance limit of the cam–roller Hertz pressure p_max (MPa): below it, no contact fatigue."""
    endurance_cycles: Annotated[float, Field(gt=0.0, le=1e12)] = 1.0e7
    """Cycles at which the endurance limit is stated."""
    bearing_rating_n: Annotated[float, Field(gt=0.0, le=1e7)] = 12_700.0
    """Dynamic load rating C of one rotary-shaft bearing (N; a 6204 deep-groove ball bearing)."""
    cam_material: str = "steel"
    """Material of the cam and the roller (a defined material)."""


class Mill(_Strict):
    """Geometry of the mill: rods, vial, cam and spring."""

    rods: Rods
    vial: Vial
    cam: Cam
    spring: Spring
    powder: Powder = Powder()
    structure: Structure = Structure()

    @model_validator(mode="after")
    def _rods_fit(self) -> Mill:
        r_r, r_v, n = self.rods.radius_mm, self.vial.radius_mm, self.rods.count
        if r_r >= r_v:
            raise ValueError(f"rods.radius_mm = {r_r} must be < vial.radius_mm = {r_v}: the rods must fit in the vial")
        if n > 1:
            # n equal circles of radius r_r centred on a circle of radius r0 = r_v - r_r
            # touch when the chord 2 r0 sin(π/n) equals 2 r_r (packing limit).
            chord_mm = 2.0 * (r_v - r_r) * math.sin(math.pi / n)
            if chord_mm < 2.0 * r_r:
                raise ValueError(
                    f"rods.count = {n} rods of radius {r_r} mm overlap on the wall of a "
                    f"{r_v} mm vial: centre spacing {chord_mm:.3f} mm < rod diameter "
                    f"{2 * r_r:.3f} mm (packing limit)"
                )
        return self


class Furnace(_Strict):
    """The furnace around the vial, and its limits."""

    ambient_temp_c: Annotated[float, Field(ge=-20.0, le=60.0)] = 25.0
    min_setpoint_c: Annotated[float, Field(ge=-20.0, le=200.0)] = 20.0
    max_setpoint_c: Annotated[float, Field(gt=0.0, le=1_600.0)] = 900.0
    over_temp_c: Annotated[float, Field(gt=0.0, le=1_700.0)] = 950.0
    max_heating_rate_c_per_min: Annotated[float, Field(gt=0.0, le=200.0)] = 20.0
    heater_power_w: Annotated[float, Field(gt=0.0, le=50_000.0)] = 1_500.0
    heat_capacity_j_per_k: Annotated[float, Field(gt=0.0, le=1e7)] = 4_000.0
    loss_w_per_k: Annotated[float, Field(gt=0.0, le=1_000.0)] = 1.2
    setpoint_refresh_s: Annotated[float, Field(gt=0.0, le=60.0)] = 3.0
    """The heater turns off when its setpoint is not refreshed within this time (s)."""
    verify_period_s: Annotated[float, Field(gt=0.0, le=600.0)] = 30.0
    verify_min_rise_c: Annotated[float, Field(gt=0.0, le=100.0)] = 2.0
    """Heater verification: heating at full power must raise the temperature this much per period."""

    @model_validator(mode="after")
    def _ordered(self) -> Furnace:
        if not self.min_setpoint_c < self.max_setpoint_c < self.over_temp_c:
            raise ValueError(
                "need min_setpoint_c < max_setpoint_c < over_temp_c, got "
                f"{self.min_setpoint_c} / {self.max_setpoint_c} / {self.over_temp_c}"
            )
        return self


class Interlock(_Strict):
    """The eq. 9 interlock (docs/safety.md)."""

    law: LimitLaw = LimitLaw.PAPER_EQ9
    margin: Annotated[float, Field(ge=0.0, le=0.5)] = 0.05
    """Fraction kept below the law's limit: ω_r ≤ (1 − margin)·ω_r,max(ω_v)."""
    debounce_samples: Annotated[int, Field(ge=1, le=50)] = 3
    """Consecutive out-of-envelope measurements that trip."""
    measurement_tolerance_rpm: Annotated[float, Field(ge=0.0, le=100.0)] = 3.0
    """Allowance for measurement noise before a measured pair counts as outside."""
    stale_periods: Annotated[float, Field(ge=2.0, le=100.0)] = 10.0
    min_stale_s: Annotated[float, Field(gt=0.0, le=60.0)] = 1.0
    """A node frame is stale after max(stale_periods × its period, min_stale_s)."""
    e2e_error_limit: Annotated[int, Field(ge=1, le=100)] = 5
    """Net E2E error score, and sequence score, that fault a link."""
    e2e_sequence_decay_frames: Annotated[int, Field(ge=1, le=1000)] = 16
    """Fresh frames per point taken off the E2E sequence score (repeated/out-of-sequence counters)."""
    startup_grace_s: Annotated[float, Field(gt=0.0, le=60.0)] = 2.0
    """After the node is first seen, a stream not yet received is judged stale only after this long (s)."""
    command_confirm_s: Annotated[float, Field(gt=0.0, le=10.0)] = 1.0
    """A command the node has not confirmed by its reported state within this time escalates (s):
    STOP → E-stop, any other → trip naming the lost command. Also the lag allowed before measured
    speeds must follow what was commanded (plus the drives' settle time)."""
    command_repeat_s: Annotated[float, Field(gt=0.0, le=5.0)] = 0.2
    """An unconfirmed command is sent again, with a fresh alive counter, this often (s); an E-stop
    is repeated at this period until the node reports it."""

    @model_validator(mode="after")
    def _repeat_within_confirm(self) -> Interlock:
        if not self.command_repeat_s < self.command_confirm_s:
            raise ValueError(
                f"command_repeat_s = {self.command_repeat_s} must be < command_confirm_s = {self.command_confirm_s}: "
                "an unconfirmed command must be repeated before it escalates"
            )
        return self


class Timing(_Strict):
    """Periods and timeouts of the controller and the node."""

    heartbeat_period_s: Annotated[float, Field(gt=0.0, le=1.0)] = 0.05
    watchdog_timeout_s: Annotated[float, Field(gt=0.0, le=10.0)] = 0.25
    node_tick_s: Annotated[float, Field(gt=0.0, le=0.5)] = 0.01
    controller_tick_s: Annotated[float, Field(gt=0.0, le=0.5)] = 0.01
    setpoint_period_s: Annotated[float, Field(gt=0.0, le=5.0)] = 0.1
    challenge_lifetime_s: Annotated[float, Field(gt=0.0, le=10.0)] = 0.5
    """How long a NodeStatus challenge may be echoed by a heartbeat (s): bounds what a replay can feed."""
    setpoint_expiry_periods: Annotated[float, Field(ge=2.0, le=100.0)] = 10.0
    min_setpoint_expiry_s: Annotated[float, Field(gt=0.0, le=60.0)] = 0.5
    """A running node whose drive setpoints are not refreshed within :attr:`setpoint_expiry_s` stops (SAFETY 26)."""

    @property
    def setpoint_expiry_s(self) -> float:
        """max(setpoint_expiry_periods × setpoint_period_s, min_setpoint_expiry_s) (s; docs/safety.md)."""
        return max(self.setpoint_expiry_periods * self.setpoint_period_s, self.min_setpoint_expiry_s)

    @model_validator(mode="after")
    def _watchdog_after_heartbeat(self) -> Timing:
        if self.watchdog_timeout_s < 2.0 * self.heartbeat_period_s:
            raise ValueError(
                f"watchdog_timeout_s = {self.watchdog_timeout_s} must be ≥ 2 × heartbeat_period_s "
                f"= {2.0 * self.heartbeat_period_s}: one lost heartbeat must not trip"
            )
        if self.challenge_lifetime_s < self.watchdog_timeout_s:
            raise ValueError(
                f"challenge_lifetime_s = {self.challenge_lifetime_s} must be ≥ watchdog_timeout_s "
                f"= {self.watchdog_timeout_s}: a few lost NodeStatus frames must not starve the watchdog "
                "(docs/protocol.md, heartbeat freshness)"
            )
        return self


class Service(_Strict):
    """Where the controller service listens and writes its records (empty paths: by convention).

    See :mod:`millctl.config.paths` and docs/deployment.md.
    """

    socket_path: str = ""
    socket_mode: Annotated[int, Field(ge=0o600, le=0o660)] = 0o600
    """The socket's permission bits: 0600 (the service's user) or 0660 (and its group); never others'."""
    tcp_port: Annotated[int, Field(ge=0, le=65_535)] = 0
    """Loopback TCP port; 0 disables TCP. TCP needs ``token_file``."""
    token_file: str = ""
    records_dir: str = ""
    rotate_bytes: Annotated[int, Field(ge=4_096, le=1 << 32)] = 16 << 20
    keep_files: Annotated[int, Field(ge=1, le=1_000)] = 10
    run_sample_s: Annotated[float, Field(ge=0.05, le=3_600.0)] = 1.0
    """How often a recipe run records a sample of the mill (s; ``millctl report`` draws them)."""
    max_request_bytes: Annotated[int, Field(ge=4_096, le=64 << 20)] = 1 << 20
    """Largest request body the API reads (bytes); a larger one is refused with 413 unread."""

    @field_validator("socket_mode")
    @classmethod
    def _socket_mode_private(cls, value: int) -> int:
        if value & 0o600 != 0o600 or value & ~0o660:
            raise ValueError(
                f"socket_mode = 0o{value:o}: use 0o600 (the service's user) or 0o660 (and its group); the owner "
                "needs rw, no permission for others, no execute bits (docs/deployment.md#permissions)"
            )
        return value


class MillConfig(_Strict):
    """The whole configuration of one mill (``config/mill.toml``)."""

    name: str = "rod mill"
    materials: dict[str, Material]
    mill: Mill
    model: Model = Model()
    drives: Drives
    furnace: Furnace = Furnace()
    interlock: Interlock = Interlock()
    timing: Timing = Timing()
    bus: Bus = Bus()
    service: Service = Service()

    @model_validator(mode="after")
    def _materials_exist(self) -> MillConfig:
        for where, name in (
            ("mill.rods.material", self.mill.rods.material),
            ("mill.vial.material", self.mill.vial.material),
            ("mill.structure.cam_material", self.mill.structure.cam_material),
        ):
            if name not in self.materials:
                known = ", ".join(sorted(self.materials)) or "none"
                raise ValueError(f"{where} = {name!r} is not a defined material (defined: {known})")
        self.drives.check_channels(self.bus)  # the furnace's channel is not the drives' own
        return self

    @property
    def rod_material(self) -> Material:
        """Material of the rods."""
        return self.materials[self.mill.rods.material]

    @property
    def vial_material(self) -> Material:
        """Material of the vial."""
        return self.materials[self.mill.vial.material]

    @property
    def rod_mass_kg(self) -> float:
        """Mass m of one rod (kg): ρ·π·r_r²·L."""
        rods = self.mill.rods
        return self.rod_material.density_kg_m3 * math.pi * rods.radius_m**2 * rods.length_m

    def omega_r_abs_max_rad_s(self) -> float:
        """Absolute rotary speed limit of the drive (rad/s)."""
        return rpm_to_rad_s(self.drives.rotary.max_speed_rpm)


__all__ = [
    "G_M_S2",
    "Bus",
    "Cam",
    "CamShape",
    "Cia402Drive",
    "Cia402Mode",
    "Drive",
    "DriveBackend",
    "Drives",
    "Furnace",
    "FurnaceBackend",
    "Interlock",
    "LimitLaw",
    "Material",
    "Mill",
    "MillConfig",
    "Model",
    "ModelVariant",
    "Powder",
    "Rods",
    "Service",
    "Spring",
    "Structure",
    "Timing",
    "Vial",
]

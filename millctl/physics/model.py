"""The mill's physical parameters in SI units, validated, and a scene (speeds and phases).

:class:`MillModel` is the params object every physics function takes; build it
from a :class:`~millctl.config.MillConfig` with :meth:`MillModel.from_config`.
Construction rejects parameters that describe no real mill with
:class:`~millctl.errors.PhysicsInputError` (negative radii, rods that do not fit,
rods that overlap at the start).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from millctl.config.models import G_M_S2, CamShape, MillConfig, ModelVariant
from millctl.errors import PhysicsInputError
from millctl.physics.cam import strokes


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0.0):
        raise PhysicsInputError(f"{name} = {value!r} must be a finite number > 0 (see docs/model.md#symbols)")


def _nonnegative(name: str, value: float) -> None:
    if not (math.isfinite(value) and value >= 0.0):
        raise PhysicsInputError(f"{name} = {value!r} must be a finite number ≥ 0 (see docs/model.md#symbols)")


@dataclass(frozen=True)
class MillModel:
    """Geometry, masses, materials and model choices of one mill (SI units)."""

    variant: ModelVariant
    rod_radius_m: float
    """r_r."""
    rod_length_m: float
    """L (the paper's l_r)."""
    rod_mass_kg: float
    """m."""
    vial_radius_m: float
    """r_v."""
    n_rods: int
    """n."""
    eccentricity_m: float
    """r_d, cam eccentricity (vibration amplitude)."""
    cam_to_vial_m: float
    """l, cam centre to vial centre at its highest point."""
    spring_n_per_m: float
    """k."""
    restitution: float = 0.0
    """e, coefficient of restitution of impacts."""
    powder_friction: float = 0.3
    """μ, rod/vial–powder friction (eqs 20, 25)."""
    rod_youngs_pa: float = 200e9
    rod_poisson: float = 0.29
    vial_youngs_pa: float = 200e9
    vial_poisson: float = 0.29
    g_m_s2: float = G_M_S2
    cam: CamShape = CamShape.SINGLE
    """Cam shape: circular single-acting (lift r_d sin α) or elliptical double-acting (r_d sin 2α)."""

    def __post_init__(self) -> None:
        for name in ("rod_radius_m", "rod_length_m", "rod_mass_kg", "vial_radius_m", "cam_to_vial_m", "g_m_s2"):
            _positive(name, getattr(self, name))
        for name in ("eccentricity_m", "spring_n_per_m", "restitution", "powder_friction"):
            _nonnegative(name, getattr(self, name))
        _positive("rod_youngs_pa", self.rod_youngs_pa)
        _positive("vial_youngs_pa", self.vial_youngs_pa)
        if self.restitution > 1.0:
            raise PhysicsInputError(f"restitution = {self.restitution} must be ≤ 1")
        for name in ("rod_poisson", "vial_poisson"):
            value = getattr(self, name)
            if not 0.0 <= value < 0.5:
                raise PhysicsInputError(f"{name} = {value} must lie in [0, 0.5)")
        if self.rod_radius_m >= self.vial_radius_m:
            raise PhysicsInputError(
                f"rod radius {self.rod_radius_m} m must be < vial radius {self.vial_radius_m} m: the rods do not fit"
            )
        if not isinstance(self.n_rods, int) or self.n_rods < 1:
            raise PhysicsInputError(f"n_rods = {self.n_rods!r} must be an integer ≥ 1")
        if self.n_rods > 1:
            spacing_m = 2.0 * self.r0_m * math.sin(math.pi / self.n_rods)
            if spacing_m < 2.0 * self.rod_radius_m:
                raise PhysicsInputError(
                    f"{self.n_rods} rods of radius {self.rod_radius_m} m overlap at the start on a wall circle of "
                    f"radius r0 = {self.r0_m} m: centre spacing {spacing_m:.6g} m < rod diameter "
                    f"{2 * self.rod_radius_m:.6g} m (packing limit)"
                )

    @property
    def r0_m(self) -> float:
        """r0 = r_v − r_r, radius of the circle the rod centres run on (m)."""
        return self.vial_radius_m - self.rod_radius_m

    @property
    def contact_distance_m(self) -> float:
        """Centre distance of two touching rods, 2 r_r (m) (eq. 13 corrected; printed 2 r_d)."""
        return 2.0 * self.rod_radius_m

    @classmethod
    def from_config(cls, config: MillConfig) -> MillModel:
        """Take every parameter from a validated configuration; the variant from ``config.model.variant``."""
        mill = config.mill
        rod_mat, vial_mat = config.rod_material, config.vial_material
        return cls(
            variant=ModelVariant(config.model.variant),
            rod_radius_m=mill.rods.radius_m,
            rod_length_m=mill.rods.length_m,
            rod_mass_kg=config.rod_mass_kg,
            vial_radius_m=mill.vial.radius_m,
            n_rods=mill.rods.count,
            eccentricity_m=mill.cam.eccentricity_m,
            cam_to_vial_m=mill.cam.cam_to_vial_m,
            spring_n_per_m=mill.spring.stiffness_n_per_m,
            restitution=config.model.restitution,
            powder_friction=config.model.powder_friction,
            rod_youngs_pa=rod_mat.youngs_modulus_pa,
            rod_poisson=rod_mat.poisson_ratio,
            vial_youngs_pa=vial_mat.youngs_modulus_pa,
            vial_poisson=vial_mat.poisson_ratio,
            cam=CamShape(mill.cam.shape),
        )


@dataclass(frozen=True)
class Scene:
    """A mill at constant speeds with initial phases: θ = θ0 + ω_r t, α = α0 + ω_v t (eqs 1–3).

    Rod i (0-based) starts pinned to the wall at θ0 + i·2π/n (eq. 11); rod 0 is
    the paper's "detached rod". ω_v and α0 are the cam motor's speed and phase;
    the physics moves the vial with the cam's lift, whose speed and phase are
    :attr:`lift_omega_rad_s` and :attr:`lift_alpha0_rad` (h·ω_v and h·α0 with h
    strokes per cam revolution, :mod:`millctl.physics.cam`).
    """

    model: MillModel
    omega_r_rad_s: float
    omega_v_rad_s: float
    theta0_rad: float = -0.5 * math.pi
    alpha0_rad: float = 0.0

    def __post_init__(self) -> None:
        for name in ("omega_r_rad_s", "omega_v_rad_s", "theta0_rad", "alpha0_rad"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise PhysicsInputError(f"{name} = {value!r} must be finite")
        if self.omega_r_rad_s < 0.0 or self.omega_v_rad_s < 0.0:
            raise PhysicsInputError(
                f"speeds must be ≥ 0 (ω_r = {self.omega_r_rad_s}, ω_v = {self.omega_v_rad_s} rad/s); "
                "a reversed drive is the mirror image of a forward one"
            )

    @property
    def lift_omega_rad_s(self) -> float:
        """Angular frequency of the cam's lift, h·ω_v (rad/s): ω_v of eqs 1–27 for this cam."""
        return strokes(self.model.cam) * self.omega_v_rad_s

    @property
    def lift_alpha0_rad(self) -> float:
        """Initial phase of the cam's lift, h·α0 (rad): α0 of eqs 1–27 for this cam."""
        return strokes(self.model.cam) * self.alpha0_rad

    def rod_theta0_rad(self, rod: int) -> float:
        """Initial angle of rod ``rod`` on the wall (rad), eq. 11."""
        return self.theta0_rad + rod * 2.0 * math.pi / self.model.n_rods


__all__ = ["MillModel", "Scene"]

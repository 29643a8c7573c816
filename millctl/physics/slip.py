"""Where the paper's no-slip assumption breaks: the carried rod needs more friction than μN.

The paper carries a rod with the wall (θ = θ0 + ω_r t, spin ω_r) until it detaches.
In the vial-centred frame (gravity g_eff = g − r_d ω_v² sin α, α = α0 + ω_v t) that
carriage needs, per unit mass,

* radially, the wall's normal force N/m = r0 ω_r² − g_eff sin θ (eqs 4–7, corrected);
* tangentially, a wall traction F_t/m = g_eff cos θ (positive along the wall's motion):
  uniform motion on the circle has no tangential acceleration, so the wall must
  cancel the tangential part of g_eff.

Coulomb friction supplies at most μN, with μ = ``model.powder_friction`` (the contact
is rod–powder–wall, the μ of eqs 20 and 25). The carriage is violated where
|F_t|/N > μ, i.e. where μ N/m ∓ g_eff cos θ < 0. Both are trig sums of time, so the
first such time is found with the certified search of
:func:`~millctl.physics.detachment.first_falling_zero`. Since N → 0 at detachment
while F_t does not, |F_t|/N → ∞ there (unless cos θ_d = 0): a carried rod always
slides before it leaves; what matters is where, and by how much (docs/model.md, slip).

Everything here is a pure function: :func:`traction_ratio` (vectorised, for
studies), :func:`no_slip_check` (one rod's carried arc). What the rod does once
it slides is :mod:`millctl.physics.slip_ride`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from millctl.config.models import ModelVariant
from millctl.physics.cam import strokes
from millctl.physics.detachment import find_detachment, first_falling_zero
from millctl.physics.kinematics import TrigSum, normal_force_per_mass
from millctl.physics.model import MillModel, Scene

FloatArray = NDArray[np.float64]


def traction_ratio(
    model: MillModel, omega_r_rad_s: float, omega_v_rad_s: float, theta_rad: ArrayLike, alpha_rad: ArrayLike
) -> FloatArray:
    """|F_t|/N of the carried rod at wall angle θ and cam phase α (vectorised); inf where N ≤ 0.

    F_t/m = g_eff cos θ, N/m = r0 ω_r² − g_eff sin θ, g_eff = g − r_d ω_v² sin α (ω_v, α of the
    cam's lift: h·ω_v and h·α for a cam of h strokes per revolution, given the motor's). The
    no-slip assumption holds where the ratio is ≤ μ (``model.powder_friction``).
    """
    theta = np.asarray(theta_rad, dtype=float)
    lift = strokes(model.cam)  # the cam's lift runs at h·ω_v, phase h·α (millctl.physics.cam)
    g_eff = model.g_m_s2 - model.eccentricity_m * (lift * omega_v_rad_s) ** 2 * np.sin(
        lift * np.asarray(alpha_rad, dtype=float)
    )
    normal = model.r0_m * omega_r_rad_s**2 - g_eff * np.sin(theta)
    traction = np.abs(g_eff * np.cos(theta))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio: FloatArray = np.where(normal > 0.0, traction / np.where(normal > 0.0, normal, 1.0), np.inf)
    return ratio


def traction_per_mass(scene: Scene, theta0_rad: float) -> TrigSum:
    """F_t(t)/m = g_eff cos θ (m/s²) of a rod carried at θ0 + ω_r t, as a trig sum of time.

    g cos θ − r_d ω_v² sin α cos θ, with sin α cos θ = ½[sin(α + θ) + sin(α − θ)].
    """
    m = scene.model
    w_r, w_v, a0 = scene.omega_r_rad_s, scene.lift_omega_rad_s, scene.lift_alpha0_rad
    half = 0.5 * m.eccentricity_m * w_v * w_v
    return TrigSum(
        constant=0.0,
        amplitudes=(m.g_m_s2, -half, -half),
        frequencies_rad_s=(w_r, w_v + w_r, w_v - w_r),
        phases_rad=(theta0_rad, a0 + theta0_rad - 0.5 * math.pi, a0 - theta0_rad - 0.5 * math.pi),
    )


def _combine(a: TrigSum, b: TrigSum, sign_b: float) -> TrigSum:
    """The trig sum a + sign_b·b."""
    return TrigSum(
        a.constant + sign_b * b.constant,
        a.amplitudes + tuple(sign_b * x for x in b.amplitudes),
        a.frequencies_rad_s + b.frequencies_rad_s,
        a.phases_rad + b.phases_rad,
    )


def carriage_margins(scene: Scene, theta0_rad: float, mu: float) -> tuple[TrigSum, TrigSum]:
    """μN/m − F_t/m and μN/m + F_t/m of a rod carried at θ0 + ω_r t (θ0 at t = 0), trig sums of time.

    N is the true normal force (corrected law) in either variant; the carriage holds while both are ≥ 0.
    """
    normal = normal_force_per_mass(scene, theta0_rad, ModelVariant.CORRECTED)
    scaled = TrigSum(
        mu * normal.constant, tuple(mu * a for a in normal.amplitudes), normal.frequencies_rad_s, normal.phases_rad
    )
    traction = traction_per_mass(scene, theta0_rad)
    return _combine(scaled, traction, -1.0), _combine(scaled, traction, 1.0)


def first_slip_s(margins: tuple[TrigSum, TrigSum], t_start_s: float, t_stop_s: float) -> float:
    """The first time in [t_start, t_stop] at which a carriage margin falls below zero (t_start: at once; inf: never).

    The second margin is searched only up to the first one's onset: a later zero of it cannot be the first.
    """
    onset = math.inf
    for margin in margins:
        if margin(t_start_s) <= 0.0:
            return t_start_s
        stop = min(t_stop_s, onset)
        if stop > t_start_s:
            root = first_falling_zero(margin, t_start_s, stop)
            if root is not None:
                onset = min(onset, root)
    return onset


@dataclass(frozen=True)
class NoSlipCheck:
    """Whether, and where, the carried rod needs more wall friction than μN before it detaches."""

    violated: bool
    onset_time_s: float
    """First time at which |F_t| > μN on the carried arc (s); nan when the carriage holds."""
    onset_theta_rad: float
    """Wall angle there (rad, in (−π, π]); nan when the carriage holds."""
    onset_alpha_rad: float
    """Cam phase there (rad, in [0, 2π)); nan when the carriage holds."""
    arc_end_s: float
    """End of the carried arc examined: the detachment time, or the horizon when the rod stays pinned."""
    detached: bool
    """The rod detaches at ``arc_end_s`` (in the model's variant)."""
    friction: float
    """μ used."""


def no_slip_check(
    scene: Scene,
    theta0_rad: float | None = None,
    t_start_s: float = 0.0,
    horizon_s: float | None = None,
    arc_end_s: float | None = None,
) -> NoSlipCheck:
    """Where on its carried arc a rod pinned at θ0 + ω_r t first needs |F_t| > μN (pure).

    The arc runs from ``t_start_s`` to the rod's detachment in the model's variant
    (``find_detachment``; default horizon one revolution), or to ``arc_end_s`` when
    given (a caller that already knows the detachment time). N is the true normal
    force (corrected law) in both variants: the paper's eq. 7 is not a force.
    """
    theta0 = scene.theta0_rad if theta0_rad is None else theta0_rad
    mu = scene.model.powder_friction
    if arc_end_s is None:
        det = find_detachment(scene, theta0, t_start_s, horizon_s)
        detached, arc_end_s = det.detached, (det.time_s if det.detached else det.horizon_s)
    else:
        detached = True
    onset = first_slip_s(carriage_margins(scene, theta0, mu), t_start_s, arc_end_s)
    if onset == math.inf:
        return NoSlipCheck(False, math.nan, math.nan, math.nan, arc_end_s, detached, mu)
    theta = math.remainder(theta0 + scene.omega_r_rad_s * onset, 2.0 * math.pi)
    alpha = (scene.alpha0_rad + scene.omega_v_rad_s * onset) % (2.0 * math.pi)
    return NoSlipCheck(True, onset, theta, alpha, arc_end_s, detached, mu)


__all__ = ["NoSlipCheck", "carriage_margins", "first_slip_s", "no_slip_check", "traction_per_mass", "traction_ratio"]

"""Detachment limits on the rotary speed: the closed forms the interlock needs.

All functions are pure and vectorised over ω_v (rad/s); they return ω_r,max
(rad/s), or 0 where a law admits no real limit (only standstill detaches
nothing and stays safe). The laws, with the paper's symbols (docs/model.md):

* ``paper-eq9``: printed eq. 9, eq. 8a with sin α = −1,
  ω_r < √((mg − (k − mω_v²) r_d) / (2 m r0)).
* ``paper-every-cycle``: eq. 8a at the paper's true worst phase. The RHS of
  eq. 7 is smallest at sin α = −sign(k − mω_v²), so the bound is
  √((mg − |k − mω_v²| r_d) / (2 m r0)); it equals printed eq. 9 only while
  k > mω_v².
* ``corrected-every-phase``: the corrected detachment law
  sin θ_d = r0 ω_r² / g_eff with g_eff = g − r_d ω_v² sin α, at the worst cam
  phase: √(g (1 − Γ) / r0), Γ = r_d ω_v² / g; no real limit once Γ ≥ 1.
* ``corrected-best-phase``: the same at the best cam phase, √(g (1 + Γ) / r0).

ω_v is the cam motor's speed; for a double-acting cam every law sees the lift
speed 2ω_v (:mod:`millctl.physics.cam`), so each envelope moves to half the ω_v.

Numerators are formed as (sum of positive terms) − (sum of negative terms),
one subtraction at the end, so that nothing cancels before it must: the
printed order mg − (k − mω_v²) r_d loses digits near its zero.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from millctl.config.models import G_M_S2, CamShape, LimitLaw, MillConfig
from millctl.physics.cam import STROKES_PER_REVOLUTION, lift_speed_array, strokes

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LimitParams:
    """The parameters the detachment limits depend on, in SI units."""

    rod_mass_kg: float
    """m, mass of one rod."""
    r0_m: float
    """r0 = r_v − r_r, radius of the circle the rod centres run on."""
    eccentricity_m: float
    """r_d, cam eccentricity (vibration amplitude)."""
    spring_n_per_m: float
    """k, spring stiffness."""
    g_m_s2: float = G_M_S2
    cam: CamShape = CamShape.SINGLE
    """The cam's shape: every law sees the lift speed h·ω_v, not the motor's ω_v (:mod:`.cam`)."""

    @classmethod
    def from_config(cls, config: MillConfig) -> LimitParams:
        """Take m, r0, r_d and k from a validated configuration."""
        mill = config.mill
        return cls(
            rod_mass_kg=config.rod_mass_kg,
            r0_m=mill.vial.radius_m - mill.rods.radius_m,
            eccentricity_m=mill.cam.eccentricity_m,
            spring_n_per_m=mill.spring.stiffness_n_per_m,
            cam=CamShape(mill.cam.shape),
        )


def _sqrt_positive(numerator: FloatArray, denominator: float) -> FloatArray:
    """√(numerator / denominator) where the numerator is positive, else 0 (no real limit)."""
    ratio = np.where(numerator > 0.0, numerator, 0.0) / denominator
    return np.sqrt(ratio)


def eq7_denominator(p: LimitParams, omega_v_rad_s: ArrayLike, sin_alpha: ArrayLike) -> FloatArray:
    """Denominator of printed eq. 7, (k − mω_v²) r_d sin α + mg (N), without early cancellation."""
    w2 = np.square(lift_speed_array(p.cam, omega_v_rad_s))
    s = np.asarray(sin_alpha, dtype=float)
    m, k, r_d = p.rod_mass_kg, p.spring_n_per_m, p.eccentricity_m
    spring_term = k * r_d * s  # sign follows sin α
    inertia_term = m * w2 * r_d * s
    positives = (
        m * p.g_m_s2 + np.where(spring_term > 0, spring_term, 0.0) - np.where(inertia_term < 0, inertia_term, 0.0)
    )
    negatives = np.where(inertia_term > 0, inertia_term, 0.0) - np.where(spring_term < 0, spring_term, 0.0)
    result: FloatArray = positives - negatives
    return result


def omega_r_max_eq8a(p: LimitParams, omega_v_rad_s: ArrayLike, sin_alpha: ArrayLike) -> FloatArray:
    """Eq. 8a: the ω_r above which printed eq. 7 has no detachment at cam phase α (rad/s)."""
    return _sqrt_positive(eq7_denominator(p, omega_v_rad_s, sin_alpha), 2.0 * p.rod_mass_kg * p.r0_m)


def omega_r_max_paper_eq9(p: LimitParams, omega_v_rad_s: ArrayLike) -> FloatArray:
    """Printed eq. 9 (rad/s): eq. 8a with sin α = −1, numerator m(g + r_d ω_v²) − k r_d."""
    w2 = np.square(lift_speed_array(p.cam, omega_v_rad_s))
    m, r_d = p.rod_mass_kg, p.eccentricity_m
    numerator = m * (p.g_m_s2 + r_d * w2) - p.spring_n_per_m * r_d
    return _sqrt_positive(numerator, 2.0 * m * p.r0_m)


def omega_r_max_paper_every_cycle(p: LimitParams, omega_v_rad_s: ArrayLike) -> FloatArray:
    """Eq. 8a at the worst phase sin α = −sign(k − mω_v²) (rad/s): mg − |k − mω_v²| r_d."""
    w2 = np.square(lift_speed_array(p.cam, omega_v_rad_s))
    m, k, r_d = p.rod_mass_kg, p.spring_n_per_m, p.eccentricity_m
    stiff = k >= m * w2
    # k ≥ mω_v²: sin α = −1 → (mg + m r_d ω_v²) − k r_d;  k < mω_v²: sin α = +1 → (mg + k r_d) − m r_d ω_v²
    numerator = np.where(stiff, m * (p.g_m_s2 + r_d * w2) - k * r_d, (m * p.g_m_s2 + k * r_d) - m * r_d * w2)
    return _sqrt_positive(numerator, 2.0 * m * p.r0_m)


def vibration_intensity(p: LimitParams, omega_v_rad_s: ArrayLike) -> FloatArray:
    """Γ = r_d ω_v² / g, the cam's peak acceleration in units of g (dimensionless)."""
    w2 = np.square(lift_speed_array(p.cam, omega_v_rad_s))
    result: FloatArray = p.eccentricity_m * w2 / p.g_m_s2
    return result


def omega_r_max_corrected_every_phase(p: LimitParams, omega_v_rad_s: ArrayLike) -> FloatArray:
    """Corrected law at the worst cam phase (rad/s): √(g(1 − Γ)/r0), 0 once Γ ≥ 1."""
    gamma = vibration_intensity(p, omega_v_rad_s)
    return _sqrt_positive(p.g_m_s2 * (1.0 - gamma), p.r0_m)


def omega_r_max_corrected_best_phase(p: LimitParams, omega_v_rad_s: ArrayLike) -> FloatArray:
    """Corrected law at the best cam phase (rad/s): √(g(1 + Γ)/r0)."""
    gamma = vibration_intensity(p, omega_v_rad_s)
    return _sqrt_positive(p.g_m_s2 * (1.0 + gamma), p.r0_m)


LAWS = {
    LimitLaw.PAPER_EQ9: omega_r_max_paper_eq9,
    LimitLaw.PAPER_EVERY_CYCLE: omega_r_max_paper_every_cycle,
    LimitLaw.CORRECTED_EVERY_PHASE: omega_r_max_corrected_every_phase,
    LimitLaw.CORRECTED_BEST_PHASE: omega_r_max_corrected_best_phase,
}
"""Every law by name: law → function(params, ω_v rad/s) → ω_r,max rad/s."""

EVERY_CYCLE_LAWS = frozenset({LimitLaw.PAPER_EVERY_CYCLE, LimitLaw.CORRECTED_EVERY_PHASE})


def omega_r_max(law: LimitLaw, p: LimitParams, omega_v_rad_s: ArrayLike) -> FloatArray:
    """ω_r,max (rad/s) under the named law."""
    return LAWS[law](p, omega_v_rad_s)


def scalar_limit(law: LimitLaw, p: LimitParams) -> Callable[[float], float]:
    """ω_r,max (rad/s) as a function of one ω_v (rad/s), in plain ``math``: the interlock's scalar path.

    The law is chosen and its constant terms (k·r_d, 2·m·r0, mg + k·r_d, the
    cam's strokes per revolution) are formed once, here; the function then
    costs a few multiplications and one square root (a fraction of a
    microsecond, docs/benchmarks.md). The formulas and their order of
    operations are those of the vectorised laws above, so every verdict is
    bitwise the same (``tests/unit/test_limits.py``).
    """
    h = STROKES_PER_REVOLUTION[p.cam]  # the lift speed h·ω_v, as lift_speed_array forms it
    m, k, r_d, g, r0 = p.rod_mass_kg, p.spring_n_per_m, p.eccentricity_m, p.g_m_s2, p.r0_m
    sqrt = math.sqrt
    if law is LimitLaw.PAPER_EQ9:  # eq. 9: √((m(g + r_d w²) − k r_d) / (2 m r0))
        k_r_d, two_m_r0 = k * r_d, 2.0 * m * r0

        def paper_eq9(omega_v_rad_s: float) -> float:
            w = h * omega_v_rad_s
            numerator = m * (g + r_d * (w * w)) - k_r_d
            return sqrt((numerator if numerator > 0.0 else 0.0) / two_m_r0)

        return paper_eq9
    if law is LimitLaw.PAPER_EVERY_CYCLE:  # eq. 8a at the true worst phase: mg − |k − m w²| r_d
        k_r_d, m_g_k_r_d, two_m_r0 = k * r_d, m * g + k * r_d, 2.0 * m * r0

        def paper_every_cycle(omega_v_rad_s: float) -> float:
            w = h * omega_v_rad_s
            w2 = w * w
            numerator = m * (g + r_d * w2) - k_r_d if k >= m * w2 else m_g_k_r_d - m * r_d * w2
            return sqrt((numerator if numerator > 0.0 else 0.0) / two_m_r0)

        return paper_every_cycle
    worst = law is LimitLaw.CORRECTED_EVERY_PHASE  # g_eff = g(1 ∓ Γ), Γ = r_d w² / g

    def corrected(omega_v_rad_s: float) -> float:
        w = h * omega_v_rad_s
        gamma = r_d * (w * w) / g
        numerator = g * (1.0 - gamma) if worst else g * (1.0 + gamma)
        return sqrt((numerator if numerator > 0.0 else 0.0) / r0)

    return corrected


def is_every_cycle_bound(law: LimitLaw, p: LimitParams, omega_v_rad_s: ArrayLike) -> NDArray[np.bool_]:
    """True where the law guarantees detachment in every cycle of its own model.

    Printed eq. 9 is the every-cycle bound only while k ≥ mω_v²; the best-phase
    law never is.
    """
    w = np.asarray(omega_v_rad_s, dtype=float)
    if law in EVERY_CYCLE_LAWS:
        return np.ones(w.shape, dtype=bool)
    if law is LimitLaw.PAPER_EQ9:
        return np.asarray(p.spring_n_per_m >= p.rod_mass_kg * np.square(lift_speed_array(p.cam, w)))
    return np.zeros(w.shape, dtype=bool)


def not_every_cycle_above_rad_s(law: LimitLaw, p: LimitParams) -> float | None:
    """The cam speed ω_v (rad/s) above which ``law`` is not the every-cycle bound; None if it always is.

    The one answer to "from where on does the configured law stop being the every-cycle bound", which
    :func:`is_every_cycle_bound` evaluates pointwise: printed eq. 9 from k = m(hω_v)² on
    (:func:`switch_omega_v_rad_s`), the best-phase law from standstill on (0), the every-cycle laws never.
    """
    if law in EVERY_CYCLE_LAWS:
        return None
    if law is LimitLaw.PAPER_EQ9:
        return switch_omega_v_rad_s(p)
    return 0.0


def switch_omega_v_rad_s(p: LimitParams) -> float:
    """The cam speed ω_v (rad/s) where k = m(hω_v)² and the paper's worst phase flips sign."""
    return float(np.sqrt(p.spring_n_per_m / p.rod_mass_kg)) / strokes(p.cam)


def eq9_vacuous_below_rad_s(p: LimitParams) -> float:
    """The cam speed up to which printed eq. 9's numerator m g − (k − m ω_v²) r_d is ≤ 0 (rad/s); 0 if never.

    The numerator is ≤ 0 while m ω_v² r_d ≤ k r_d − m g, i.e. for ω_v ≤ √(k/m − g/r_d) when k r_d > m g:
    there eq. 9 admits no rotation at all (the law is vacuous). With k a per-rod effective stiffness
    (Set A: 92 N/m, k r_d = 0.092 N against m g = 0.869 N) that never happens; a platform spring rate
    read as k (10⁴–10⁵ N/m) makes eq. 9 vacuous over any drivable cam speed (docs/model.md, errata k).
    """
    m, k, r_d = p.rod_mass_kg, p.spring_n_per_m, p.eccentricity_m
    excess = k * r_d - m * p.g_m_s2
    if r_d <= 0.0 or excess <= 0.0:
        return 0.0
    return float(np.sqrt(excess / (m * r_d)))


def sin_alpha_bound_consistent(p: LimitParams, omega_v_rad_s: ArrayLike) -> FloatArray:
    """The cam phase bound that follows from eq. 7 (the dimensionally consistent eq. 8b).

    Eq. 7 has a real detachment angle only while mg + (k − mω_v²) r_d sin α > 0,
    i.e. sin α > −mg / ((k − mω_v²) r_d) when k > mω_v² (a lower bound), and
    sin α < mg / ((mω_v² − k) r_d) when k < mω_v² (an upper bound). Returns that
    bound; ±inf where k = mω_v² (every phase admissible).
    """
    w2 = np.square(lift_speed_array(p.cam, omega_v_rad_s))
    excess = (p.spring_n_per_m - p.rod_mass_kg * w2) * p.eccentricity_m
    with np.errstate(divide="ignore"):
        result: FloatArray = -p.rod_mass_kg * p.g_m_s2 / excess
    return result


def sin_alpha_bound_printed_eq8b(p: LimitParams, omega_v_rad_s: ArrayLike) -> FloatArray:
    """Printed eq. 8b's right side, m(ω_v² r_d − g)/k (dimensionally inconsistent; kept for the errata)."""
    w2 = np.square(lift_speed_array(p.cam, omega_v_rad_s))
    result: FloatArray = p.rod_mass_kg * (w2 * p.eccentricity_m - p.g_m_s2) / p.spring_n_per_m
    return result


@dataclass(frozen=True)
class RegimeFlags:
    """Where a limit table leaves the paper's comfortable assumptions (arrays over ω_v)."""

    no_real_limit: NDArray[np.bool_]
    """The configured law gives no real ω_r,max: only standstill is inside."""
    spring_below_inertia: NDArray[np.bool_]
    """k < mω_v²: printed eq. 9 is the paper's most permissive phase, not its worst."""
    gamma_ge_1: NDArray[np.bool_]
    """Γ ≥ 1: the cam's downward acceleration exceeds g at some phase."""


def regime_flags(law: LimitLaw, p: LimitParams, omega_v_rad_s: ArrayLike) -> RegimeFlags:
    """Evaluate the regime flags of a law over ω_v (rad/s)."""
    w = np.asarray(omega_v_rad_s, dtype=float)
    return RegimeFlags(
        no_real_limit=omega_r_max(law, p, w) <= 0.0,
        spring_below_inertia=p.spring_n_per_m < p.rod_mass_kg * np.square(lift_speed_array(p.cam, w)),
        gamma_ge_1=vibration_intensity(p, w) >= 1.0,
    )


__all__ = [
    "EVERY_CYCLE_LAWS",
    "LAWS",
    "LimitParams",
    "RegimeFlags",
    "eq7_denominator",
    "eq9_vacuous_below_rad_s",
    "is_every_cycle_bound",
    "not_every_cycle_above_rad_s",
    "omega_r_max",
    "omega_r_max_corrected_best_phase",
    "omega_r_max_corrected_every_phase",
    "omega_r_max_eq8a",
    "omega_r_max_paper_eq9",
    "omega_r_max_paper_every_cycle",
    "regime_flags",
    "scalar_limit",
    "sin_alpha_bound_consistent",
    "sin_alpha_bound_printed_eq8b",
    "switch_omega_v_rad_s",
    "vibration_intensity",
]

"""The slip ride of a held rod inside the multi-rod simulation (level c): stick, slide, regrip or detach.

:mod:`millctl.physics.slip_ride` follows one rod with ``solve_ivp``; level (c) needs the same physics as
events of its loop, in two engines that agree event for event. The rod is the block of
``slip_ride`` with its spin locked to the wall's (j = 0, the paper's premise; level (s) rides the same):
per unit mass, in the vial-centred frame (g_eff = g − r_d ω_v² sin α of the cam's lift),

    n = r0 φ̇² − g_eff sin φ,        r0 φ̈ = f − g_eff cos φ,

* stick: φ̇ = ω_r (the paper's carriage), f = g_eff cos φ, valid while |f| ≤ μ n; the first time it is
  not (:func:`stick_slip_onset`: :func:`millctl.physics.slip.first_slip_s` of the carriage margins) the rod slides;
* slide, in direction s = sign(f) at the onset: f = s μ n; stepped by classical Runge–Kutta (order 4) in
  steps of :func:`slide_step_s`; within a step the first of n ≤ 0 (detach) and s(φ̇ − ω_r) ≥ 0 (the
  contact point has caught up with the wall: regrip) is located by bisection of the step length
  (:func:`slide_step`);
* regrip: φ̇ = ω_r exactly, and the stick is tried again (slide on the other way if |f| > μ n);
* detach: the rod leaves with its own φ̇ (not ω_r): the flight's velocity r0 φ̇ θ̂, N = 0 (the wall gap's
  triple root, as at a falling zero of N).

For the contact search a sliding rod moves along the chord of each step: uniform turning at the step's
mean rate (φ1 − φ0)/h, so that a held rod is always θ0 + w (t − t0) (``WallState.rate_offset_rad_s`` =
w − ω_r). Between the steps' ends the chord is within h²|φ̈|/8 of the ride (about 2e-4 rad at 1/32 of
the shortest time scale); at the ends it is the Runge–Kutta ride, within ~1e-7 rad of ``slip_ride.ride``
(tests/unit/physics/test_wall_slide.py). Held rods ride independently: the search looks for contacts of
flying rods only, so two sliding rods on the wall may pass through each other (docs/model.md, slip).

The compiled engine (:mod:`millctl.physics.kernels.slide`) is this module line for line.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from millctl.errors import PhysicsInputError
from millctl.physics.events import shortest_time_s
from millctl.physics.kinematics import g_eff_m_s2
from millctl.physics.model import Scene
from millctl.physics.slip import carriage_margins, first_slip_s

STEPS_PER_SCALE = 32
"""Slide steps per shortest time scale (the cam's lift period, the revolution, the fall time √(2 r_r/g))."""
BISECTIONS = 64
"""Halvings of a step that locate a detachment or regrip inside it (below the time's rounding)."""
N_NEAR_ZERO = 1e-9
"""n (m/s²) within this × (r0 ω_r² + g + r_d ω_v²) of zero at a slide's start is zero (rounding, not a sign)."""
MAX_CHANGES = 64
"""Stick ↔ slide changes of one held ride after which the rod is carried to its detachment (a chatter guard)."""

SLIDE_STEP, REGRIP, DETACH = 0, 1, 2
"""What ends a slide step: nothing (the next step follows), the regrip, the detachment."""


class SlideStep(NamedTuple):
    """One step of a slide: how it ends, its length and the ride's state at its end."""

    ends: int
    """:data:`SLIDE_STEP`, :data:`REGRIP` or :data:`DETACH`."""
    h_s: float
    theta_rad: float
    rate_rad_s: float


def slide_step_s(scene: Scene, steps_per_scale: int = STEPS_PER_SCALE) -> float:
    """The slide's Runge–Kutta step (s): 1/``steps_per_scale`` of the shortest time scale.

    The step's error falls as its fourth power: ``python -m bench --only study`` prints the first
    detachment's time and angle against solve_ivp's ride at 8–64 steps a scale, and the cost of each.
    """
    return shortest_time_s(scene) / check_slide_steps(steps_per_scale)


def check_slide_steps(steps_per_scale: int) -> int:
    """``steps_per_scale`` as a whole number ≥ 1, or :class:`PhysicsInputError` naming it."""
    if isinstance(steps_per_scale, bool) or not isinstance(steps_per_scale, int) or steps_per_scale < 1:
        raise PhysicsInputError(
            f"slide_steps = {steps_per_scale!r} must be a whole number ≥ 1 of slide steps per shortest time scale "
            f"(default {STEPS_PER_SCALE}; docs/model.md, 'Level (c) with the slip ride')"
        )
    return steps_per_scale


def _accel(scene: Scene, t: float, phi: float, rate: float, s: float, mu: float) -> tuple[float, float]:
    """(n, φ̈) of the sliding block: n = r0 φ̇² − g_eff sin φ, r0 φ̈ = s μ n − g_eff cos φ."""
    g_eff = g_eff_m_s2(scene, t)
    r0 = scene.model.r0_m
    n = r0 * rate * rate - g_eff * math.sin(phi)
    return n, (s * mu * n - g_eff * math.cos(phi)) / r0


def _rk4(scene: Scene, t: float, phi: float, rate: float, s: float, mu: float, h: float) -> tuple[float, float]:
    """(φ, φ̇) after one classical Runge–Kutta step of length h from (φ, φ̇) at t."""
    _, a1 = _accel(scene, t, phi, rate, s, mu)
    p2, r2 = phi + 0.5 * h * rate, rate + 0.5 * h * a1
    _, a2 = _accel(scene, t + 0.5 * h, p2, r2, s, mu)
    p3, r3 = phi + 0.5 * h * r2, rate + 0.5 * h * a2
    _, a3 = _accel(scene, t + 0.5 * h, p3, r3, s, mu)
    p4, r4 = phi + h * r3, rate + h * a3
    _, a4 = _accel(scene, t + h, p4, r4, s, mu)
    return phi + h / 6.0 * (rate + 2.0 * r2 + 2.0 * r3 + r4), rate + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)


def _ends(scene: Scene, t: float, phi: float, rate: float, s: float, mu: float) -> int:
    """How the ride stands at (t, φ, φ̇): detached (n ≤ 0), regripped (s(φ̇ − ω_r) ≥ 0), or still sliding."""
    n, _ = _accel(scene, t, phi, rate, s, mu)
    if n <= 0.0:
        return DETACH
    if s * (rate - scene.omega_r_rad_s) >= 0.0:
        return REGRIP
    return SLIDE_STEP


def slide_step(scene: Scene, t_s: float, theta_rad: float, rate_rad_s: float, s: float, mu: float,
               h_max_s: float) -> SlideStep:  # fmt: skip
    """One slide step from (φ, φ̇) at t, up to ``h_max_s``; cut at a detachment or regrip inside it.

    With n < 0 already at t beyond rounding (a slide that would begin where the wall cannot press: the paper's
    eq. 7 held the rod, the true N did not) it ends at once, length 0: the rod leaves unsupported. Within
    :data:`N_NEAR_ZERO` of zero (a rod carried through a dip starts where N has just risen through 0) the
    slide begins, and the step decides.
    """
    m = scene.model
    scale = m.r0_m * scene.omega_r_rad_s**2 + m.g_m_s2 + m.eccentricity_m * scene.lift_omega_rad_s**2
    if _accel(scene, t_s, theta_rad, rate_rad_s, s, mu)[0] < -N_NEAR_ZERO * scale:
        return SlideStep(DETACH, 0.0, theta_rad, rate_rad_s)
    phi, rate = _rk4(scene, t_s, theta_rad, rate_rad_s, s, mu, h_max_s)
    ends = _ends(scene, t_s + h_max_s, phi, rate, s, mu)
    if ends == SLIDE_STEP:
        return SlideStep(SLIDE_STEP, h_max_s, phi, rate)
    lo, hi = 0.0, h_max_s
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        p_mid, r_mid = _rk4(scene, t_s, theta_rad, rate_rad_s, s, mu, mid)
        if _ends(scene, t_s + mid, p_mid, r_mid, s, mu) == SLIDE_STEP:
            lo = mid
        else:
            hi, phi, rate = mid, p_mid, r_mid
    return SlideStep(_ends(scene, t_s + hi, phi, rate, s, mu), hi, phi, rate)


def stick_slip_onset(scene: Scene, theta_at_zero_rad: float, t_start_s: float, t_stop_s: float, mu: float) -> float:
    """First time in [t_start, t_stop] at which the carried rod needs |F_t| > μN (t_start: at once; inf: never)."""
    return first_slip_s(carriage_margins(scene, theta_at_zero_rad, mu), t_start_s, t_stop_s)


def slide_direction(scene: Scene, t_s: float, theta_rad: float) -> float:
    """The sign s of the traction the carriage needs at (t, θ): +1 along the wall's motion, −1 against it."""
    return 1.0 if g_eff_m_s2(scene, t_s) * math.cos(theta_rad) > 0.0 else -1.0


__all__ = [
    "BISECTIONS",
    "DETACH",
    "MAX_CHANGES",
    "N_NEAR_ZERO",
    "REGRIP",
    "SLIDE_STEP",
    "STEPS_PER_SCALE",
    "SlideStep",
    "check_slide_steps",
    "slide_direction",
    "slide_step",
    "slide_step_s",
    "stick_slip_onset",
]

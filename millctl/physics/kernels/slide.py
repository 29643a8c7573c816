"""Level (c) compiled: the slip ride of a held rod, line for line :mod:`millctl.physics.wall_slide`.

The block on the wall with its spin locked (per unit mass, g_eff = g − r_d ω_v² sin α of the cam's lift):
n = r0 φ̇² − g_eff sin φ, r0 φ̈ = s μ n − g_eff cos φ while it slides in direction s; carried (φ̇ = ω_r)
while |g_eff cos φ| ≤ μ n. The stick's end is the certified search of level (b) (:func:`.telemetry._slip_onset`,
run in a clock that starts at the pin); a slide is stepped by classical Runge–Kutta and a detachment (n ≤ 0)
or regrip (s(φ̇ − ω_r) ≥ 0) inside a step located by bisection of the step's length.

Work of the slip ride, one tuple ``slip`` (:func:`_slip_work`): (μ, margin rows, a zeroed state row, a scene
row shifted in time, the slide step). μ = inf: no slip, the paper's carriage.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from millctl.physics.kernels.layout import _A0, _G, _R0, _RD, _STATE_COLUMNS, _TRIG_COLUMNS, _WR, _WV
from millctl.physics.kernels.many_contacts import _shortest_time_s
from millctl.physics.kernels.telemetry import _slip_onset
from millctl.physics.wall_slide import BISECTIONS, DETACH, N_NEAR_ZERO, REGRIP, SLIDE_STEP


@njit(cache=True)
def _slide_step_s(p, steps_per_scale):  # type: ignore[no-untyped-def]
    """wall_slide.slide_step_s: 1/steps_per_scale of the shortest time scale (lift period, revolution, fall)."""
    return _shortest_time_s(p) / steps_per_scale


@njit(cache=True)
def _slip_work(p, mu, steps_per_scale):  # type: ignore[no-untyped-def]
    """The ``slip`` tuple of a run at friction μ (inf: no slip), its slide steps ``steps_per_scale`` a scale."""
    rows, st1 = np.zeros((2, _TRIG_COLUMNS)), np.zeros((1, _STATE_COLUMNS))
    return mu, rows, st1, p.copy(), _slide_step_s(p, steps_per_scale)


@njit(cache=True)
def _g_eff(p, t):  # type: ignore[no-untyped-def]
    w = p[_WV]
    return p[_G] - p[_RD] * w * w * math.sin(p[_A0] + w * t)


@njit(cache=True)
def _accel(p, t, phi, rate, s, mu):  # type: ignore[no-untyped-def]
    """wall_slide._accel: (n, φ̈) of the sliding block."""
    g_eff = _g_eff(p, t)
    n = p[_R0] * rate * rate - g_eff * math.sin(phi)
    return n, (s * mu * n - g_eff * math.cos(phi)) / p[_R0]


@njit(cache=True)
def _rk4(p, t, phi, rate, s, mu, h):  # type: ignore[no-untyped-def]
    """wall_slide._rk4: (φ, φ̇) after one classical Runge–Kutta step of length h."""
    _, a1 = _accel(p, t, phi, rate, s, mu)
    p2, r2 = phi + 0.5 * h * rate, rate + 0.5 * h * a1
    _, a2 = _accel(p, t + 0.5 * h, p2, r2, s, mu)
    p3, r3 = phi + 0.5 * h * r2, rate + 0.5 * h * a2
    _, a3 = _accel(p, t + 0.5 * h, p3, r3, s, mu)
    p4, r4 = phi + h * r3, rate + h * a3
    _, a4 = _accel(p, t + h, p4, r4, s, mu)
    return phi + h / 6.0 * (rate + 2.0 * r2 + 2.0 * r3 + r4), rate + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)


@njit(cache=True)
def _ends(p, t, phi, rate, s, mu):  # type: ignore[no-untyped-def]
    """wall_slide._ends: DETACH (n ≤ 0), REGRIP (s(φ̇ − ω_r) ≥ 0) or SLIDE_STEP."""
    n, _ = _accel(p, t, phi, rate, s, mu)
    if n <= 0.0:
        return DETACH
    if s * (rate - p[_WR]) >= 0.0:
        return REGRIP
    return SLIDE_STEP


@njit(cache=True)
def _slide_step(p, t, theta, rate, s, mu, h_max):  # type: ignore[no-untyped-def]
    """wall_slide.slide_step: (how it ends, its length, φ, φ̇ at its end); length 0 with n < 0 at t."""
    scale = p[_R0] * p[_WR] ** 2 + p[_G] + p[_RD] * p[_WV] ** 2
    if _accel(p, t, theta, rate, s, mu)[0] < -N_NEAR_ZERO * scale:
        return DETACH, 0.0, theta, rate
    phi, r = _rk4(p, t, theta, rate, s, mu, h_max)
    ends = _ends(p, t + h_max, phi, r, s, mu)
    if ends == SLIDE_STEP:
        return SLIDE_STEP, h_max, phi, r
    lo, hi = 0.0, h_max
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        p_mid, r_mid = _rk4(p, t, theta, rate, s, mu, mid)
        if _ends(p, t + mid, p_mid, r_mid, s, mu) == SLIDE_STEP:
            lo = mid
        else:
            hi, phi, r = mid, p_mid, r_mid
    return _ends(p, t + hi, phi, r, s, mu), hi, phi, r


@njit(cache=True)
def _stick_onset(p, theta_start, t_start, t_stop, slip):  # type: ignore[no-untyped-def]
    """wall_slide.stick_slip_onset for a rod carried from θ at t_start: the first time |F_t| > μN, or inf.

    The level-(b) search runs in a clock that starts at t_start (the scene row's cam phase moved there).
    """
    mu, rows, st1, shifted, _ = slip
    shifted[_A0] = p[_A0] + p[_WV] * t_start
    onset = _slip_onset(shifted, theta_start, mu, t_stop - t_start, rows, st1)
    return t_start + onset if onset < math.inf else math.inf


@njit(cache=True)
def _slide_direction(p, t, theta):  # type: ignore[no-untyped-def]
    """wall_slide.slide_direction: +1 where the carriage needs traction along the wall's motion, else −1."""
    return 1.0 if _g_eff(p, t) * math.cos(theta) > 0.0 else -1.0


__all__: list[str] = []

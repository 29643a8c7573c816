"""Rod states in vial-centred coordinates: pinned to the wall, or in free flight (eq. 10 with τ = t − t_0).

Positions are relative to the vial centre c(t), which moves with the cam; in that
frame a pinned rod is r0·(cos θ, sin θ) and a flying rod is

    d(τ) = d_0 + u_0 τ + h(τ) ŷ,   h(τ) = −½ g τ² − r_d [sin(α_0 + ω_v τ) − sin α_0 − ω_v τ cos α_0],

where u_0 is the rod's velocity relative to the vial centre at t_0 (the lab
velocity of eq. 2 minus the vial's own r_d ω_v cos α). The stable reduced forms
h/τ² and (h/τ² + ½ g_eff,0)/τ let the wall gap of a departing rod be divided by
its known triple root (:func:`departure_wall_gap`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from millctl.physics.model import Scene

FloatArray = NDArray[np.float64]

_FACT = [math.factorial(k) for k in range(40)]


def _c2_plus_half_over_x(x: float) -> float:
    """((cos x − 1)/x² + ½)/x, stable at small x."""
    if abs(x) < 1.0:
        return float(sum((-1) ** k * x ** (2 * k - 3) / _FACT[2 * k] for k in range(2, 12)))
    return ((math.cos(x) - 1.0) / (x * x) + 0.5) / x


def _s3(x: float) -> float:
    """(sin x − x)/x³, stable at small x."""
    if abs(x) < 1.0:
        return float(sum((-1) ** k * x ** (2 * k - 2) / _FACT[2 * k + 1] for k in range(1, 12)))
    return (math.sin(x) - x) / (x * x * x)


@dataclass(frozen=True)
class WallState:
    """A rod held on the wall from t_0 on, at angle θ_0 + w (t − t_0), w = ω_r + ``rate_offset_rad_s``.

    Carried (the paper's picture) the offset is 0; a rod sliding on the wall (:mod:`.wall_slide`) moves
    along the chord of its slide step, at that step's mean rate.
    """

    t0_s: float
    theta0_rad: float
    rate_offset_rad_s: float = 0.0

    def rate_rad_s(self, scene: Scene) -> float:
        """W (rad/s): ω_r carried, the slide step's mean rate sliding."""
        return scene.omega_r_rad_s + self.rate_offset_rad_s

    def rel(self, scene: Scene, t_s: float) -> tuple[float, float, float, float]:
        """(x, y, vx, vy) relative to the vial centre (m, m/s)."""
        r0, w = scene.model.r0_m, self.rate_rad_s(scene)
        th = self.theta0_rad + w * (t_s - self.t0_s)
        c, s = math.cos(th), math.sin(th)
        return r0 * c, r0 * s, -r0 * w * s, r0 * w * c

    def rel_array(self, scene: Scene, t_s: FloatArray) -> tuple[FloatArray, ...]:
        """Vectorised :meth:`rel`."""
        r0, w = scene.model.r0_m, self.rate_rad_s(scene)
        th = self.theta0_rad + w * (t_s - self.t0_s)
        c, s = np.cos(th), np.sin(th)
        return r0 * c, r0 * s, -r0 * w * s, r0 * w * c


@dataclass(frozen=True)
class FlightState:
    """A rod in free flight from t_0: position d_0 and velocity u_0 relative to the vial centre."""

    t0_s: float
    x0_m: float
    y0_m: float
    ux0_m_s: float
    uy0_m_s: float
    from_wall: bool = False
    """True when the flight starts with the rod on the wall (departure: the wall gap has a triple root)."""
    departure_rate_offset_rad_s: float = 0.0
    """From the wall: its departure rate φ̇_d − ω_r (0 carried; a sliding rod leaves at its own φ̇_d)."""

    def _alpha0(self, scene: Scene) -> float:
        return scene.lift_alpha0_rad + scene.lift_omega_rad_s * self.t0_s

    def rel(self, scene: Scene, t_s: float) -> tuple[float, float, float, float]:
        """(x, y, vx, vy) relative to the vial centre (m, m/s)."""
        return self.rel_tau(scene, t_s - self.t0_s)

    def rel_tau(self, scene: Scene, tau_s: float) -> tuple[float, float, float, float]:
        """(x, y, vx, vy) relative to the vial centre at τ = t − t_0 after the flight began (m, m/s).

        The event search works in τ, so a flight time is resolved to its own rounding
        and never formed as the difference of two absolute times (docs/model.md, eq. 10).
        """
        tau = tau_s  # the flight's own clock
        r_d, w, g = scene.model.eccentricity_m, scene.lift_omega_rad_s, scene.model.g_m_s2
        a0 = self._alpha0(scene)
        h = -0.5 * g * tau * tau - r_d * (math.sin(a0 + w * tau) - math.sin(a0) - w * tau * math.cos(a0))
        dh = -g * tau - r_d * w * (math.cos(a0 + w * tau) - math.cos(a0))
        return self.x0_m + self.ux0_m_s * tau, self.y0_m + self.uy0_m_s * tau + h, self.ux0_m_s, self.uy0_m_s + dh

    def rel_array(self, scene: Scene, t_s: FloatArray) -> tuple[FloatArray, ...]:
        """Vectorised :meth:`rel`."""
        tau = t_s - self.t0_s
        r_d, w, g = scene.model.eccentricity_m, scene.lift_omega_rad_s, scene.model.g_m_s2
        a0 = self._alpha0(scene)
        h = -0.5 * g * tau * tau - r_d * (np.sin(a0 + w * tau) - math.sin(a0) - w * tau * math.cos(a0))
        dh = -g * tau - r_d * w * (np.cos(a0 + w * tau) - math.cos(a0))
        x = self.x0_m + self.ux0_m_s * tau
        return x, self.y0_m + self.uy0_m_s * tau + h, np.full_like(tau, self.ux0_m_s), self.uy0_m_s + dh


RodState = WallState | FlightState


def depart(scene: Scene, wall: WallState, t_d_s: float) -> FlightState:
    """The flight that starts when a pinned rod detaches at t_d (eq. 2's velocity, relative to the vial)."""
    x, y, vx, vy = wall.rel(scene, t_d_s)
    return FlightState(t_d_s, x, y, vx, vy, from_wall=True)


def depart_sliding(scene: Scene, t_d_s: float, theta_rad: float, rate_rad_s: float) -> FlightState:
    """The flight of a rod that leaves the wall while sliding, at φ_d with its own rate φ̇_d (:mod:`.wall_slide`)."""
    r0 = scene.model.r0_m
    c, s = math.cos(theta_rad), math.sin(theta_rad)
    offset = rate_rad_s - scene.omega_r_rad_s
    w = scene.omega_r_rad_s + offset
    return FlightState(t_d_s, r0 * c, r0 * s, -r0 * w * s, r0 * w * c, from_wall=True,
                       departure_rate_offset_rad_s=offset)  # fmt: skip


def departure_wall_gap(scene: Scene, flight: FlightState, n_d_m2_s2: float, tau_s: float) -> float:
    """(r0² − |d|²)/τ² for a departing rod, or /τ³ when N_d = 0 (the triple root divided out).

    ``n_d_m2_s2`` is r0·N_true(t_d)/m, the τ⁰ coefficient of (|d|² − r0²)/τ²: 0 by
    construction in the corrected variant, where it is dropped exactly so that
    rounding cannot fake a collision at departure. Positive while the rod is
    inside the wall circle. ``tau_s`` is the time since departure, τ = t − t_d (s).
    """
    tau = tau_s  # the flight's own clock
    r0, w_r, w_v = scene.model.r0_m, scene.omega_r_rad_s + flight.departure_rate_offset_rad_s, scene.lift_omega_rad_s
    r_d, g = scene.model.eccentricity_m, scene.model.g_m_s2
    a0 = flight._alpha0(scene)
    s_d, c_d = flight.y0_m / r0, flight.x0_m / r0
    x = w_v * tau
    sa, ca = math.sin(a0), math.cos(a0)
    # η = h/τ², η0 = η(0) = −½ g_eff,0, dη = (η − η0)/τ
    d_eta = -r_d * w_v**3 * (sa * _c2_plus_half_over_x(x) + ca * _s3(x))
    eta0 = -0.5 * g + 0.5 * r_d * w_v * w_v * sa
    eta = eta0 + d_eta * tau
    reduced = 2.0 * r0 * (d_eta * s_d + eta * w_r * c_d) + eta * eta * tau
    if n_d_m2_s2 == 0.0:
        return -reduced
    return -(n_d_m2_s2 + tau * reduced)


ZERO_FLIGHT_RTOL = 1e-12
"""A departure whose reduced wall gap at τ = 0 is ≤ this × its scale is a zero-length flight (docs/model.md)."""


def departure_gap_scale(scene: Scene, n_d_m2_s2: float, rate_offset_rad_s: float = 0.0) -> float:
    """The size of the terms of :func:`departure_wall_gap` at τ = 0 (its units: m²/s³ when n_d = 0, else m²/s²).

    ``rate_offset_rad_s``: the flight's departure rate φ̇_d − ω_r (0: carried).
    """
    m = scene.model
    w_r, w_v, r_d, g, r0 = (scene.omega_r_rad_s + rate_offset_rad_s, scene.lift_omega_rad_s, m.eccentricity_m,
                            m.g_m_s2, m.r0_m)  # fmt: skip
    if n_d_m2_s2 == 0.0:
        return 2.0 * r0 * (r_d * w_v**3 + (g + r_d * w_v * w_v) * w_r)
    return r0 * (r0 * w_r * w_r + g + r_d * w_v * w_v)


def zero_length_departure(scene: Scene, flight: FlightState, n_d_m2_s2: float) -> bool:
    """True when the free path of a rod leaving the wall does not leave it: no flight, no impact.

    The wall gap with the departure root divided out, at the departure instant, is
    its leading coefficient; ≤ ``ZERO_FLIGHT_RTOL`` × its scale (rounding level or
    below) means the rod would enter the wall at once (the paper's detachment where
    the true N > 0, or N touching zero with zero slope). Every engine applies this one rule.
    """
    gap = departure_wall_gap(scene, flight, n_d_m2_s2, 0.0)
    return gap <= ZERO_FLIGHT_RTOL * departure_gap_scale(scene, n_d_m2_s2, flight.departure_rate_offset_rad_s)


__all__ = [
    "ZERO_FLIGHT_RTOL",
    "FlightState",
    "RodState",
    "WallState",
    "depart",
    "depart_sliding",
    "departure_gap_scale",
    "departure_wall_gap",
    "zero_length_departure",
]

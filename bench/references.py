"""Reference first impacts: the closed form where r_d = 0, the independent scan + mpmath (40 digits) elsewhere.

With r_d = 0 (corrected variant) a rod leaves the wall at sin θ_d = r0 ω_r²/g
(or at t = 0 where it starts unsupported), flies a parabola and lands after
the flight time of :func:`~millctl.physics.reference.closed_form_flight_time_s`; the contact
point, the relative normal velocity and the energy follow in closed form. The
closed form is used when the independent reference (:mod:`bench.independent`, which
never sees an engine's answer) says the first impact is that rod's wall landing; the
two are cross-checked and the largest disagreement is reported with the results.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import mpmath

from bench.independent import independent_first_impact
from millctl.config import ModelVariant
from millctl.physics.impact import impact_energy_j
from millctl.physics.methods import ImpactEvent
from millctl.physics.model import Scene

REFERENCE_DIGITS = 40


@dataclass(frozen=True)
class Reference:
    """A scene's reference first impact (None: nothing touches before t_end) and how it was obtained."""

    event: ImpactEvent | None
    kind: str
    """"closed-form", "independent-40" or "none"."""
    closed_vs_mpmath_s: float = math.nan
    """|t_closed − t_mpmath| (s) where both exist."""

    def to_json(self) -> dict[str, object]:
        """Plain dict for the results file."""
        return {
            "event": None if self.event is None else asdict(self.event),
            "kind": self.kind,
            "closed_vs_mpmath_s": self.closed_vs_mpmath_s,
        }


def closed_form_wall_landing(scene: Scene, rod: int, digits: int = REFERENCE_DIGITS) -> ImpactEvent | None:
    """Rod ``rod``'s first wall landing with r_d = 0 in the corrected variant, in closed form (else None).

    Evaluated in mpmath at ``digits`` digits: near θ_d = 90° asin is ill-conditioned, and a
    float evaluation of the closed form would carry its own rounding into the reference.
    """
    m = scene.model
    if m.eccentricity_m != 0.0 or m.variant is not ModelVariant.CORRECTED or scene.omega_r_rad_s <= 0.0:
        return None
    with mpmath.workdps(digits):
        mpf = mpmath.mpf
        w, r0, g = mpf(scene.omega_r_rad_s), mpf(m.r0_m), mpf(m.g_m_s2)
        s_d = r0 * w * w / g
        theta0 = mpf(scene.theta0_rad) + rod * 2 * mpmath.pi / m.n_rods
        if mpmath.sin(theta0) >= s_d:  # starts unsupported: leaves at once with N < 0
            t_d, theta_d = mpf(0), theta0
        elif s_d > 1:
            return None  # pinned for ever
        else:
            theta_d = mpmath.asin(s_d)
            t_d = mpmath.fmod(mpmath.fmod(theta_d - theta0, 2 * mpmath.pi) + 2 * mpmath.pi, 2 * mpmath.pi) / w
        n_d = min(r0 * (r0 * w * w - g * mpmath.sin(theta_d)), mpf(0))
        a = r0 * w * mpmath.cos(theta_d)
        tau = 2 * (a + mpmath.sqrt(a * a - n_d)) / g  # closed_form_flight_time_s, in mpmath
        ux, uy = -r0 * w * mpmath.sin(theta_d), r0 * w * mpmath.cos(theta_d)
        x = r0 * mpmath.cos(theta_d) + ux * tau
        y = r0 * mpmath.sin(theta_d) + uy * tau - g * tau * tau / 2
        vx, vy = ux, uy - g * tau
        norm = mpmath.sqrt(x * x + y * y)
        nx, ny = x / norm, y / norm
        rvx, rvy = vx + w * y, vy - w * x  # relative to the turning wall
        v_n, v_t = float(rvx * nx + rvy * ny), float(rvy * nx - rvx * ny)
        speed = float(mpmath.sqrt(vx * vx + vy * vy))
        px = float(x + mpf(m.rod_radius_m) * nx)
        py = float(mpf(m.cam_to_vial_m) + y + mpf(m.rod_radius_m) * ny)
        t_c = float(t_d + tau)
    energy = impact_energy_j(m, v_n, speed, True)
    return ImpactEvent(t_c, rod, -1, px, py, v_n, speed, energy, "closed-form", v_t)


def reference(scene: Scene, digits: int = REFERENCE_DIGITS) -> Reference:
    """The scene's reference first impact, independent of every engine (:mod:`bench.independent`).

    Where r_d = 0 the closed form of the same rod's wall landing is the reference instead,
    and its distance to the independent one is recorded as a cross-check.
    """
    ind = independent_first_impact(scene, digits=digits)
    if ind is None:
        return Reference(None, "none")
    if ind.partner == -1:
        closed = closed_form_wall_landing(scene, ind.rod)
        if closed is not None:
            return Reference(closed, "closed-form", abs(closed.time_s - ind.time_s))
    return Reference(ind, f"independent-{digits}")

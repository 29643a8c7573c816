"""References for the benchmark and the tests: a closed form (r_d = 0) and an mpmath evaluation.

* :func:`closed_form_flight_time_s`: with r_d = 0 the wall gap of a departing rod
  is τ²·(n_d − r0 g ω_r cos θ_d τ + g² τ²/4) with n_d = r0 (r0 ω_r² − g sin θ_d);
  the flight time is 2 (r0 ω_r cos θ_d + √((r0 ω_r cos θ_d)² − n_d)) / g, i.e.
  4 r0 ω_r cos θ_d / g when the rod leaves with N = 0 (the corrected law).
* :func:`reference_first_impact`: the exact engine's first impact recomputed in
  mpmath at ``digits`` significant digits — detachment times by findroot on N(t)
  (eq. 7 or the corrected law), free flight (eq. 10) and the contact root by
  findroot on the separation, all from formulas written out again in mpmath.
  The float engine only supplies which pair touches and the starting guesses.
"""

from __future__ import annotations

import math
from typing import Any

import mpmath

from millctl.config.models import ModelVariant
from millctl.errors import PhysicsInputError
from millctl.physics.impact import impact_energy_j
from millctl.physics.methods import ImpactEvent, first_impact
from millctl.physics.model import Scene
from millctl.physics.simulate import simulate


def closed_form_flight_time_s(
    r0_m: float, omega_r_rad_s: float, theta_d_rad: float, g_m_s2: float, n_d_m2_s2: float = 0.0
) -> float:
    """Flight time (s) from the wall back to the wall with r_d = 0 (see module docstring)."""
    a = r0_m * omega_r_rad_s * math.cos(theta_d_rad)
    disc = a * a - n_d_m2_s2
    if disc < 0.0:
        raise PhysicsInputError(f"no flight: (r0 ω cos θ_d)² − n_d = {disc} < 0")
    return 2.0 * (a + math.sqrt(disc)) / g_m_s2


class _Mp:
    """The scene's kinematics written out in mpmath."""

    def __init__(self, scene: Scene) -> None:
        m = scene.model
        mpf = mpmath.mpf
        self.scene = scene
        self.r0, self.rr = mpf(m.r0_m), mpf(m.rod_radius_m)
        self.g, self.rd, self.l = mpf(m.g_m_s2), mpf(m.eccentricity_m), mpf(m.cam_to_vial_m)
        self.wr, self.wv = mpf(scene.omega_r_rad_s), mpf(scene.lift_omega_rad_s)
        self.a0 = mpf(scene.lift_alpha0_rad)
        self.k_over_m = mpf(m.spring_n_per_m) / mpf(m.rod_mass_kg)

    def theta0(self, rod: int) -> Any:
        return mpmath.mpf(self.scene.theta0_rad) + rod * 2 * mpmath.pi / self.scene.model.n_rods

    def normal(self, rod: int, t: Any) -> Any:
        th, al = self.theta0(rod) + self.wr * t, self.a0 + self.wv * t
        if self.scene.model.variant is ModelVariant.CORRECTED:
            return self.r0 * self.wr**2 - (self.g - self.rd * self.wv**2 * mpmath.sin(al)) * mpmath.sin(th)
        return 2 * self.r0 * self.wr**2 - (
            self.g + (self.k_over_m - self.wv**2) * self.rd * mpmath.sin(al)
        ) * mpmath.sin(th)

    def rel(self, rod: int, t_d: Any, t: Any) -> tuple[Any, Any, Any, Any]:
        """Position and velocity relative to the vial centre; t_d None: pinned."""
        if t_d is None or t <= t_d:
            th = self.theta0(rod) + self.wr * t
            return (
                self.r0 * mpmath.cos(th),
                self.r0 * mpmath.sin(th),
                -self.r0 * self.wr * mpmath.sin(th),
                self.r0 * self.wr * mpmath.cos(th),
            )
        x0, y0, ux, uy = self.rel(rod, None, t_d)
        tau, ad = t - t_d, self.a0 + self.wv * t_d
        h = -self.g * tau**2 / 2 - self.rd * (
            mpmath.sin(ad + self.wv * tau) - mpmath.sin(ad) - self.wv * tau * mpmath.cos(ad)
        )
        dh = -self.g * tau - self.rd * self.wv * (mpmath.cos(ad + self.wv * tau) - mpmath.cos(ad))
        return x0 + ux * tau, y0 + uy * tau + h, ux, uy + dh


def reference_first_impact(scene: Scene, digits: int = 40, t_end_s: float = 5.0) -> ImpactEvent | None:
    """The exact engine's first impact, recomputed in mpmath at ``digits`` digits (see module docstring)."""
    approx = first_impact(scene, "exact", t_end_s=t_end_s)
    if approx is None:
        return None
    run = simulate(scene, t_end_s, stop_after_first=True)
    detach = {int(r["rod"]): float(r["time_s"]) for r in run.detachments}
    with mpmath.workdps(digits):
        mp = _Mp(scene)
        t_d: dict[int, Any] = {}
        for rod, t in detach.items():
            if t == 0.0 and mp.normal(rod, mpmath.mpf(0)) <= 0:
                t_d[rod] = mpmath.mpf(0)
            else:
                t_d[rod] = mpmath.findroot(lambda s, r=rod: mp.normal(r, s), mpmath.mpf(t))
        i, j = approx.rod, approx.partner

        def sep(t: Any) -> Any:
            x, y, _, _ = mp.rel(i, t_d.get(i), t)
            if j < 0:
                return mp.r0**2 - x * x - y * y
            xb, yb, _, _ = mp.rel(j, t_d.get(j), t)
            return (x - xb) ** 2 + (y - yb) ** 2 - 4 * mp.rr**2

        t_c = mpmath.findroot(sep, mpmath.mpf(approx.time_s))
        return impact_at(mp, i, j, t_d, t_c, f"mpmath-{digits}")


def impact_at(mp: _Mp, i: int, j: int, t_d: dict[int, Any], t_c: Any, label: str) -> ImpactEvent:
    """The impact of rod i on j (−1 the wall) at t_c, every quantity in mpmath (``t_d``: departures so far)."""
    scene = mp.scene
    x, y, vx, vy = mp.rel(i, t_d.get(i), t_c)
    if j < 0:
        nx, ny = x, y
        rvx, rvy = vx + mp.wr * y, vy - mp.wr * x
    else:
        xb, yb, vxb, vyb = mp.rel(j, t_d.get(j), t_c)
        nx, ny, rvx, rvy = xb - x, yb - y, vx - vxb, vy - vyb
    norm = mpmath.sqrt(nx * nx + ny * ny)
    nx, ny = nx / norm, ny / norm
    al = mp.a0 + mp.wv * t_c
    yc = mp.l - mp.rd + mp.rd * mpmath.sin(al)
    vyc = mp.rd * mp.wv * mpmath.cos(al)
    v_n = float(rvx * nx + rvy * ny)
    speed = float(mpmath.sqrt(vx * vx + (vy + vyc) ** 2))
    px, py = float(x + mp.rr * nx), float(yc + y + mp.rr * ny)
    backed = j < 0 or j not in t_d or t_d[j] >= t_c
    energy = impact_energy_j(scene.model, v_n, speed, bool(backed))
    v_t = float(rvy * nx - rvx * ny)
    return ImpactEvent(float(t_c), i, j, px, py, v_n, speed, energy, label, v_t)


__all__ = ["closed_form_flight_time_s", "impact_at", "reference_first_impact"]

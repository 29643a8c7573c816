"""Baseline for the benchmark: the flying rods integrated by ``scipy.integrate.solve_ivp`` with events.

In vial-centred coordinates a flying rod obeys ẍ = 0, ÿ = −g + r_d ω_v² sin α(t)
(the vial's acceleration moved to the other side). The integration runs from
detachment to detachment (exact detachment times, shared with every method);
events are the wall separation r0² − |d|² and each rod pair's |Δ|² − (2 r_r)²,
falling through zero, terminal. Pinned rods are evaluated in closed form.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from millctl.errors import PhysicsInputError
from millctl.physics.detachment import find_detachment
from millctl.physics.events import ContactRow
from millctl.physics.flight import FlightState, WallState, depart
from millctl.physics.model import Scene

FloatArray = NDArray[np.float64]


class _Event:
    """A terminal, falling event function for solve_ivp."""

    terminal = True
    direction = -1.0

    def __init__(self, scene: Scene, slots: dict[int, int], rod: int, partner: int, wall: WallState | None) -> None:
        self.scene, self.slots, self.rod, self.partner, self.wall = scene, slots, rod, partner, wall

    def __call__(self, t: float, y: FloatArray) -> float:
        k = 4 * self.slots[self.rod]
        x, yy = float(y[k]), float(y[k + 1])
        m = self.scene.model
        if self.partner < 0:
            return m.r0_m**2 - (x * x + yy * yy)
        if self.partner in self.slots:
            j = 4 * self.slots[self.partner]
            xb, yb = float(y[j]), float(y[j + 1])
        else:
            assert self.wall is not None
            xb, yb, _, _ = self.wall.rel(self.scene, t)
        return (x - xb) ** 2 + (yy - yb) ** 2 - m.contact_distance_m**2


def ivp_first_contact(scene: Scene, tol: float, t_end_s: float = 5.0, method: str = "DOP853") -> ContactRow | None:
    """The first contact found by solve_ivp's event location, or None.

    ``tol`` is solve_ivp's rtol; atol = tol·r0 for positions and tol·r0·ω for velocities.
    """
    if not (math.isfinite(tol) and tol > 0.0):
        raise PhysicsInputError(f"tol = {tol} must be > 0")
    m, n = scene.model, scene.model.n_rods
    walls = [WallState(0.0, scene.rod_theta0_rad(i)) for i in range(n)]
    departures: list[tuple[float, int, FlightState]] = []
    for i in range(n):
        det = find_detachment(scene, walls[i].theta0_rad, 0.0, t_end_s)
        if det.detached:
            departures.append((det.time_s, i, depart(scene, walls[i], det.time_s)))
    departures.sort()
    slots: dict[int, int] = {}
    y0 = np.zeros(0)
    g, r_d, w_v, a0 = m.g_m_s2, m.eccentricity_m, scene.lift_omega_rad_s, scene.lift_alpha0_rad

    def rhs(t: float, y: FloatArray) -> FloatArray:
        out = np.empty_like(y)
        out[0::4], out[1::4] = y[2::4], y[3::4]
        out[2::4] = 0.0
        out[3::4] = -g + r_d * w_v * w_v * math.sin(a0 + w_v * t)
        return out

    for k, (t_a, rod, flight) in enumerate(departures):
        slots[rod] = len(slots)
        y0 = np.concatenate((y0, [flight.x0_m, flight.y0_m, flight.ux0_m_s, flight.uy0_m_s]))
        t_b = departures[k + 1][0] if k + 1 < len(departures) else t_end_s
        if t_b <= t_a:
            continue
        events = []
        for i in slots:
            events.append(_Event(scene, slots, i, -1, None))
            for j in range(n):
                if j != i and not (j in slots and j < i):
                    events.append(_Event(scene, slots, i, j, None if j in slots else walls[j]))
        sol = solve_ivp(rhs, (t_a, t_b), y0, method=method, rtol=tol, atol=tol * m.r0_m, events=events)
        if sol.status == 1:
            times = [float(te[0]) if len(te) else math.inf for te in sol.t_events]
            e = int(np.argmin(times))
            return _contact(scene, slots, events[e], times[e], np.asarray(sol.y_events[e][0]))
        y0 = np.asarray(sol.y[:, -1])
    return None


def _contact(scene: Scene, slots: dict[int, int], ev: _Event, t: float, y: FloatArray) -> ContactRow:
    m = scene.model
    k = 4 * slots[ev.rod]
    x, yy, vx, vy = (float(v) for v in y[k : k + 4])
    alpha = scene.lift_alpha0_rad + scene.lift_omega_rad_s * t
    yc = m.cam_to_vial_m - m.eccentricity_m + m.eccentricity_m * math.sin(alpha)
    vyc = m.eccentricity_m * scene.lift_omega_rad_s * math.cos(alpha)
    if ev.partner < 0:
        dx, dy = x, yy
        rvx, rvy = vx + scene.omega_r_rad_s * yy, vy - scene.omega_r_rad_s * x
    else:
        if ev.partner in slots:
            j = 4 * slots[ev.partner]
            xb, yb, vxb, vyb = (float(v) for v in y[j : j + 4])
        else:
            assert ev.wall is not None
            xb, yb, vxb, vyb = ev.wall.rel(scene, t)
        dx, dy, rvx, rvy = xb - x, yb - yy, vx - vxb, vy - vyb
    norm = math.hypot(dx, dy)
    nx, ny = dx / norm, dy / norm
    r = m.rod_radius_m
    backed = ev.partner < 0 or ev.partner not in slots
    v_n, v_t = rvx * nx + rvy * ny, rvy * nx - rvx * ny
    return ContactRow(t, ev.rod, ev.partner, x + r * nx, yc + yy + r * ny, v_n, v_t, math.hypot(vx, vy + vyc), backed)


__all__ = ["ivp_first_contact"]

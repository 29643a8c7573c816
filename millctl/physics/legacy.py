"""The paper's own collision schemes, kept as ``legacy`` for comparison (eqs 14–17).

Fixed time step dt from the first detachment; after every step the paper's
check is applied in absolute (lab) coordinates, as the paper writes it:

* rods: (x_1 − x_i)² + (y_1 − y_i)² ≤ (2 r_r)² (eq. 14, with the corrected contact
  distance 2 r_r);
* wall, ``legacy``: |p − c|² ≥ r0² (the exact circle, checked at step ends);
* wall, ``legacy-arcs``: the wall as q points on the bore (radius r_v), anchored at
  each rod's detachment point and turning with the vial (eq. 15 with the angles
  θ_d + (j − 1)2π/q + ω_r τ), contact when a point is within r_r (eq. 17).

On the first step that passes a check the collision is placed at the average of
the step's end points (time, contact point, velocities): first order in dt. With
``interpolate=True`` the time is instead the linear interpolation of the
separation between the end points (second order), the method's optional upgrade.
Detachment times are the exact ones, so only the collision schemes differ.
Absolute coordinates and the check at every step make a departing rod look
touching when dt is tiny (rounding of l + r0 swamps the τ³ gap): the failure
MODEL-NOTES warns about, which the exact engine avoids.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from millctl.errors import PhysicsInputError
from millctl.physics.detachment import find_detachment
from millctl.physics.events import ContactRow
from millctl.physics.flight import FlightState, WallState, depart
from millctl.physics.model import MillModel, Scene

FloatArray = NDArray[np.float64]
_CHUNK = 256


def _lab_arrays(scene: Scene, wall: WallState, flight: FlightState | None, ts: FloatArray) -> tuple[FloatArray, ...]:
    """Absolute (x, y, vx, vy) of one rod at times ts: pinned before its detachment, flying after."""
    xw, yw, vxw, vyw = wall.rel_array(scene, ts)
    if flight is not None:
        xf, yf, vxf, vyf = flight.rel_array(scene, ts)
        flying = ts >= flight.t0_s
        xw, yw = np.where(flying, xf, xw), np.where(flying, yf, yw)
        vxw, vyw = np.where(flying, vxf, vxw), np.where(flying, vyf, vyw)
    m = scene.model
    alpha = scene.lift_alpha0_rad + scene.lift_omega_rad_s * ts
    yc = m.cam_to_vial_m - m.eccentricity_m + m.eccentricity_m * np.sin(alpha)
    vyc = m.eccentricity_m * scene.lift_omega_rad_s * np.cos(alpha)
    return xw, yc + yw, vxw, vyc + vyw, yc, vyc


def legacy_first_contact(
    scene: Scene, dt_s: float, q: int | None = None, t_end_s: float = 5.0, interpolate: bool = False
) -> ContactRow | None:
    """The first contact by the paper's scheme, or None.

    ``q`` None uses the exact circle for the wall; an integer uses q arcs.
    """
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise PhysicsInputError(f"dt = {dt_s} s must be a finite step > 0")
    if q is not None and q < 3:
        raise PhysicsInputError(f"q = {q} arcs must be ≥ 3")
    n = scene.model.n_rods
    walls = [WallState(0.0, scene.rod_theta0_rad(i)) for i in range(n)]
    flights: list[FlightState | None] = []
    for i in range(n):
        det = find_detachment(scene, walls[i].theta0_rad, 0.0, t_end_s)
        flights.append(depart(scene, walls[i], det.time_s) if det.detached else None)
    starts = [f.t0_s for f in flights if f is not None]
    if not starts:
        return None
    t0 = min(starts)
    k0 = 1
    while t0 + (k0 - 1) * dt_s < t_end_s:
        ts = t0 + dt_s * np.arange(k0 - 1, k0 + _CHUNK, dtype=float)  # one step of overlap
        lab = [_lab_arrays(scene, walls[i], flights[i], ts) for i in range(n)]
        seps = _separations(scene, lab, flights, ts, q)
        stacked = np.stack(list(seps.values()))
        hits = np.flatnonzero((stacked[:, 1:] <= 0.0).any(axis=0))
        if hits.size:
            k = int(hits[0]) + 1
            pair = next(p for p, sep in seps.items() if sep[k] <= 0.0)
            t, i, j, x, y, v_n, v_t, speed = _averaged(scene, lab, seps, pair, ts, k, interpolate)
            # m_eff = m when either body is held by the wall (the wall itself, or a pinned rod), m/2 when
            # both rods fly; the pair's order says nothing about which of the two is the one in flight
            backed = j < 0 or not (_flying(flights[i], t) and _flying(flights[j], t))
            return ContactRow(t, i, j, x, y, v_n, v_t, speed, backed)
        k0 += _CHUNK
    return None


def _flying(flight: FlightState | None, t_s: float) -> bool:
    """True when a rod has left the wall by time t_s (s)."""
    return flight is not None and flight.t0_s < t_s


def _separations(
    scene: Scene, lab: list[tuple[FloatArray, ...]], flights: list[FlightState | None], ts: FloatArray, q: int | None
) -> dict[tuple[int, int], FloatArray]:
    """Separation (> 0 apart) of every pair with a flying rod, per time; (i, −1) is the wall."""
    m = scene.model
    out: dict[tuple[int, int], FloatArray] = {}
    for i, f in enumerate(flights):
        if f is None:
            continue
        flying = ts > f.t0_s
        x, y, _, _, yc, _ = lab[i]
        if q is None:
            sep = m.r0_m**2 - (x * x + (y - yc) ** 2)
        else:
            # the nearest of the q points is one of the two that bracket the rod's angle (O(1) per step)
            tau = ts - f.t0_s
            base = math.atan2(f.y0_m, f.x0_m) + scene.omega_r_rad_s * tau
            spacing = 2.0 * math.pi / q
            lower = base + spacing * np.floor((np.arctan2(y - yc, x) - base) / spacing)
            d2 = np.full_like(ts, np.inf)
            for angle in (lower, lower + spacing):
                ax, ay = m.vial_radius_m * np.cos(angle), yc + m.vial_radius_m * np.sin(angle)
                d2 = np.minimum(d2, (x - ax) ** 2 + (y - ay) ** 2)
            sep = d2 - m.rod_radius_m**2
        out[(i, -1)] = np.where(flying, sep, np.inf)
        for j in range(len(flights)):
            if j == i or (j < i and flights[j] is not None):
                continue
            xj, yj = lab[j][0], lab[j][1]
            both = flying | (ts > (flights[j].t0_s if flights[j] is not None else math.inf))  # type: ignore[union-attr]
            sep_r = (x - xj) ** 2 + (y - yj) ** 2 - (2.0 * m.rod_radius_m) ** 2
            out[(i, j)] = np.where(both, sep_r, np.inf)
    return out


def _averaged(
    scene: Scene,
    lab: list[tuple[FloatArray, ...]],
    seps: dict[tuple[int, int], FloatArray],
    pair: tuple[int, int],
    ts: FloatArray,
    k: int,
    interpolate: bool,
) -> tuple[float, int, int, float, float, float, float, float]:
    """The paper's answer: the average of the step's end points (or the interpolated time)."""
    i, j = pair

    def at(rod: int, idx: int) -> tuple[float, ...]:
        return tuple(float(a[idx]) for a in lab[rod])

    a0, a1 = at(i, k - 1), at(i, k)
    t_prev = float(ts[k - 1])
    w = 0.5
    if interpolate:
        s0, s1 = float(seps[pair][k - 1]), float(seps[pair][k])
        w = s0 / (s0 - s1) if math.isfinite(s0) and s0 > s1 else 1.0
    t = t_prev + w * (float(ts[k]) - t_prev)
    rod = [(1 - w) * u + w * v for u, v in zip(a0, a1, strict=True)]
    x, y, vx, vy, yc, vyc = rod
    r = scene.model.rod_radius_m
    if j == -1:
        dx, dy = x, y - yc
        wall_vx, wall_vy = -scene.omega_r_rad_s * dy, vyc + scene.omega_r_rad_s * dx
        rvx, rvy = vx - wall_vx, vy - wall_vy
    else:
        b0, b1 = at(j, k - 1), at(j, k)
        xb, yb, vxb, vyb, _, _ = ((1 - w) * u + w * v for u, v in zip(b0, b1, strict=True))
        dx, dy, rvx, rvy = xb - x, yb - y, vx - vxb, vy - vyb
    norm = math.hypot(dx, dy)
    nx, ny = dx / norm, dy / norm
    return t, i, j, x + r * nx, y + r * ny, rvx * nx + rvy * ny, rvy * nx - rvx * ny, math.hypot(vx, vy)


def arc_wall_sink_m(model: MillModel, q: int) -> float:
    """How far a rod centre sinks beyond r0 between two of the q wall points (m), eqs 15–17, exact.

    The deepest spot is midway between two points at angles ±π/q on the bore (radius r_v);
    the rod (radius r_r) touches them when its centre is at ρ = r_v cos(π/q) − √(r_r² − r_v² sin²(π/q)),
    so the sink is ρ − r0 (leading order :func:`arc_wall_sink_leading_m`).
    """
    if q < 3:
        raise PhysicsInputError(f"q = {q} arcs must be ≥ 3")
    half = math.pi / q
    r_v, r_r = model.vial_radius_m, model.rod_radius_m
    reach = r_r * r_r - (r_v * math.sin(half)) ** 2
    if reach <= 0.0:
        raise PhysicsInputError(f"q = {q}: the gap between two wall points exceeds the rod diameter")
    # ρ − r0 = r_r − √reach − r_v (1 − cos φ), each difference formed without cancellation
    cos_defect = 2.0 * math.sin(0.5 * half) ** 2
    return (r_v * math.sin(half)) ** 2 / (r_r + math.sqrt(reach)) - r_v * cos_defect


def arc_wall_sink_leading_m(model: MillModel, q: int) -> float:
    """Leading order of :func:`arc_wall_sink_m`: π² r_v r0 / (2 r_r q²) (m); relative error below (π r_v/(q r_r))²."""
    return math.pi**2 * model.vial_radius_m * model.r0_m / (2.0 * model.rod_radius_m * q * q)


__all__ = ["arc_wall_sink_leading_m", "arc_wall_sink_m", "legacy_first_contact"]

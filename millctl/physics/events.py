"""Exact collision events: bracket the separation function, then brentq (eqs 10–14, corrected).

Separations are positive while apart and computed in vial-centred coordinates:
wall: r0² − |d|² (the exact wall |p − c| = r0, not the paper's q arcs); rod–rod:
|d_i − d_j|² − (2 r_r)² (eq. 13 with 2 r_r, not the printed 2 r_d). For a rod that
has just left the wall, the wall separation is evaluated divided by its known
root at departure (:func:`~millctl.physics.flight.departure_wall_gap`).

Bracketing samples the separation and its exact time derivative on a grid
(vectorised); a zero crossing is bracketed directly, and a local minimum (the
derivative turning from − to +) is located by brentq on the derivative, so a
grazing contact that dips below zero between two samples is not missed. The
brentq is :func:`.roots.brentq` (scipy's algorithm without importing scipy: the
node's telemetry reaches this module).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from millctl.physics.flight import FlightState, RodState, WallState, departure_wall_gap, zero_length_departure
from millctl.physics.model import Scene
from millctl.physics.roots import brentq

WALL = -1
"""Partner index of the vial wall."""

_RTOL = 4.0 * 2.220446049250313e-16
_SCAN_SAMPLES = 32


class ContactRow(NamedTuple):
    """A located contact as the comparison methods report it (lab frame, SI)."""

    time_s: float
    rod: int
    partner: int
    x_m: float
    y_m: float
    normal_velocity_m_s: float
    tangential_velocity_m_s: float
    speed_abs_m_s: float
    backed: bool
    """The partner is the wall or a rod held by it (m_eff = m)."""


@dataclass(frozen=True)
class Contact:
    """A located contact: time, the two parties, and their relative motion along the contact normal."""

    time_s: float
    rod: int
    partner: int
    """Index of the other rod, or :data:`WALL`."""
    normal_x: float
    normal_y: float
    """Unit normal from the rod's centre towards the partner (outward for the wall)."""
    normal_velocity_m_s: float
    """Approach speed along the normal (> 0 approaching)."""
    tangential_velocity_m_s: float
    """Sliding speed of the rod's surface against the partner's (m/s)."""
    flight_time_s: float = math.nan
    """Time since the rod's flight began (departure or last bounce), τ (s): the root itself, located in
    the flight's own clock, never the difference of two absolute times (docs/model.md, eq. 10)."""


def shortest_time_s(scene: Scene) -> float:
    """The shortest of the cam's lift period, the revolution and the fall time √(2 r_r/g) (s)."""
    m = scene.model
    scales = [math.sqrt(2.0 * m.rod_radius_m / m.g_m_s2)]
    for w in (scene.lift_omega_rad_s, scene.omega_r_rad_s):
        if w > 0.0:
            scales.append(2.0 * math.pi / w)
    return min(scales)


def scan_step_s(scene: Scene) -> float:
    """Bracketing step (s): 1/16 of the shortest time scale (:func:`shortest_time_s`)."""
    return shortest_time_s(scene) / 16.0


def _wall_sep(scene: Scene, s: RodState) -> tuple[Callable[[float], float], Callable[[float], float]]:
    r0sq = scene.model.r0_m**2

    def sep(t: float) -> float:
        x, y, _, _ = s.rel(scene, t)
        return r0sq - (x * x + y * y)

    def dsep(t: float) -> float:
        x, y, vx, vy = s.rel(scene, t)
        return -2.0 * (x * vx + y * vy)

    return sep, dsep


def _rod_sep(scene: Scene, a: RodState, b: RodState) -> tuple[Callable[[float], float], Callable[[float], float]]:
    c2 = scene.model.contact_distance_m**2

    def sep(t: float) -> float:
        xa, ya, _, _ = a.rel(scene, t)
        xb, yb, _, _ = b.rel(scene, t)
        return (xa - xb) ** 2 + (ya - yb) ** 2 - c2

    def dsep(t: float) -> float:
        xa, ya, vxa, vya = a.rel(scene, t)
        xb, yb, vxb, vyb = b.rel(scene, t)
        return 2.0 * ((xa - xb) * (vxa - vxb) + (ya - yb) * (vya - vyb))

    return sep, dsep


def _accel_bound(scene: Scene, states: list[RodState]) -> float:
    """Bound on any rod's acceleration in the vial frame (m/s²): g + r_d ω_v² in flight, r0 w² held.

    w is ω_r for a carried rod, its slide step's mean rate for a sliding one (:mod:`.wall_slide`).
    """
    m = scene.model
    w2 = scene.omega_r_rad_s**2
    for s in states:
        if isinstance(s, WallState):
            w2 = max(w2, s.rate_rad_s(scene) ** 2)
    return max(m.g_m_s2 + m.eccentricity_m * scene.lift_omega_rad_s**2, m.r0_m * w2)


def _scan_arrays(scene: Scene, a: RodState, b: RodState | None, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Separation, its derivative, and the largest sampled relative speed squared."""
    xa, ya, vxa, vya = a.rel_array(scene, t)
    if b is None:
        v2 = float(np.max(vxa * vxa + vya * vya))
        return scene.model.r0_m**2 - (xa * xa + ya * ya), -2.0 * (xa * vxa + ya * vya), v2
    xb, yb, vxb, vyb = b.rel_array(scene, t)
    dx, dy, dvx, dvy = xa - xb, ya - yb, vxa - vxb, vya - vyb
    v2 = float(np.max(dvx * dvx + dvy * dvy))
    return dx * dx + dy * dy - scene.model.contact_distance_m**2, 2.0 * (dx * dvx + dy * dvy), v2


def _root(f: Callable[[float], float], a: float, b: float, tol_s: float = 0.0) -> float:
    """Root by brentq to ``tol_s`` (s); 0 means as tight as floating point allows (≈ 4 ulp)."""
    fb = f(b)
    if fb == 0.0:
        return b
    xtol = max(tol_s, _RTOL * max(abs(a), abs(b)), 1e-300)  # a root at t = 0 has no relative scale
    return brentq(f, a, b, xtol=xtol, rtol=_RTOL, maxiter=200)


def first_contact_time(
    scene: Scene,
    a: RodState,
    b: RodState | None,
    t_start_s: float,
    t_end_s: float,
    n_d_m2_s2: float = 0.0,
) -> float | None:
    """First time in [t_start, t_end] at which rod state ``a`` touches ``b`` (None = the wall); None if it does not.

    ``n_d_m2_s2`` is r0·N_true/m at departure, used only for the wall of a rod
    that departs at t_start (see :func:`departure_wall_gap`).
    """
    departing = b is None and isinstance(a, FlightState) and a.from_wall and a.t0_s == t_start_s
    sep, dsep = _wall_sep(scene, a) if b is None else _rod_sep(scene, a, b)
    sign_sep = sep
    if departing:
        assert isinstance(a, FlightState)
        flight = a

        def sign_sep(t: float) -> float:
            return departure_wall_gap(scene, flight, n_d_m2_s2, t - flight.t0_s)

    if departing:
        assert isinstance(a, FlightState)
        if zero_length_departure(scene, a, n_d_m2_s2):
            return t_start_s
    elif sign_sep(t_start_s) <= 0.0:
        return t_start_s
    h = scan_step_s(scene)
    accel = 2.0 * _accel_bound(scene, [a] if b is None else [a, b])
    t_prev, s_prev, ds_prev = t_start_s, sign_sep(t_start_s), dsep(t_start_s)
    while t_prev < t_end_s:
        n = _SCAN_SAMPLES
        ts = np.minimum(t_prev + h * np.arange(1, n + 1), t_end_s)
        s_arr, ds_arr, v2 = _scan_arrays(scene, a, b, ts)
        # |s''| = 2 |v_rel² + Δ·a_rel| ≤ 2 ((v + A h)² + 2 r0 · 2A): a minimum between two samples
        # with both ends above M h²/8 cannot reach zero (second-order bound), so it is skipped.
        curvature = 2.0 * ((math.sqrt(v2) + 2.0 * accel * h) ** 2 + 4.0 * scene.model.r0_m * accel)
        margin = curvature * h * h / 8.0
        if departing:
            tiny = np.abs(s_arr) < 1e-9 * scene.model.r0_m**2
            for k in np.flatnonzero(tiny):
                s_arr[k] = sign_sep(float(ts[k]))
        ds_before = np.concatenate(([ds_prev], ds_arr[:-1]))
        s_before = np.concatenate(([s_prev], s_arr[:-1]))
        low = np.minimum(s_before, s_arr) <= margin
        hits = (s_arr <= 0.0) | ((ds_before < 0.0) & (ds_arr > 0.0) & low)
        t_before = np.concatenate(([t_prev], ts[:-1]))
        for k in np.flatnonzero(hits & (ts > t_before)):
            t_a, t_k = float(t_before[k]), float(ts[k])
            if s_arr[k] <= 0.0:
                return _root(sign_sep, t_a, t_k)
            t_m = _root(dsep, t_a, t_k)
            if sign_sep(t_m) <= 0.0:
                return _root(sign_sep, t_a, t_m)
        t_prev, s_prev, ds_prev = float(ts[-1]), float(s_arr[-1]), float(ds_arr[-1])
    return None


def contact_kinematics(
    scene: Scene, states: list[RodState], rod: int, partner: int, t_s: float, flight_time_s: float = math.nan
) -> Contact:
    """Normal and tangential relative velocities of ``rod`` against ``partner`` at t (τ = ``flight_time_s``)."""
    x, y, vx, vy = states[rod].rel(scene, t_s)
    if partner == WALL:
        r = math.hypot(x, y)
        nx, ny = x / r, y / r
        w = scene.omega_r_rad_s
        wall_vx, wall_vy = -w * y, w * x  # the wall point beside the rod centre moves with the vial
        rvx, rvy = vx - wall_vx, vy - wall_vy
    else:
        xb, yb, vxb, vyb = states[partner].rel(scene, t_s)
        dx, dy = xb - x, yb - y
        r = math.hypot(dx, dy)
        nx, ny = dx / r, dy / r
        rvx, rvy = vx - vxb, vy - vyb
    v_n = rvx * nx + rvy * ny
    v_t = -rvx * ny + rvy * nx
    return Contact(t_s, rod, partner, nx, ny, v_n, v_t, flight_time_s)


def earliest_contact(
    scene: Scene,
    states: list[RodState],
    t_start_s: float,
    t_end_s: float,
    n_d: dict[int, float] | None = None,
    rods: list[int] | None = None,
    excluded: set[tuple[int, int]] | None = None,
    tol_s: float = 0.0,
) -> Contact | None:
    """The first contact in [t_start, t_end] among the given states (each rod with its own state).

    All pairs are scanned together on one vectorised grid; candidate intervals
    are then resolved exactly (brentq) in time order. Pairs of two pinned rods
    never touch (they move together). ``rods`` limits the search to contacts
    that involve those rods (default: every flying rod). ``n_d`` maps a rod that
    departs from the wall at t_start to r0·N_true/m there. Pairs (i < j) in
    ``excluded`` are not tested. ``tol_s`` is the root finder's absolute time
    tolerance (0: ≈ 4 ulp). Roots are found in each mover's own clock τ = t − t_0
    (:attr:`Contact.flight_time_s`), so a short flight late in a run keeps its digits.
    """
    n_d = n_d or {}
    flying = [i for i, s in enumerate(states) if isinstance(s, FlightState)]
    movers = flying if rods is None else [i for i in rods if isinstance(states[i], FlightState)]
    if not movers:
        return None
    pairs: list[tuple[int, int]] = [(i, WALL) for i in movers]
    seen: set[tuple[int, int]] = set()
    for i in movers:
        for j in range(len(states)):
            key = (min(i, j), max(i, j))
            if j != i and key not in seen and key not in (excluded or ()):
                seen.add(key)
                pairs.append((i, j))
    funcs = [_pair_functions(scene, states, i, j, t_start_s, n_d.get(i, 0.0)) for i, j in pairs]
    t_ref = [states[i].t0_s for i, _ in pairs]
    h = scan_step_s(scene)
    accel = 2.0 * _accel_bound(scene, states)
    r0 = scene.model.r0_m
    ii = np.array([i for i, _ in pairs])
    jj = np.array([j for _, j in pairs])
    wall = jj == WALL
    jj_safe = np.where(wall, ii, jj)
    c2 = scene.model.contact_distance_m**2

    def pair_arrays(ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Separation, its derivative and the relative velocity squared of every pair at times ts."""
        x, y, vx, vy = _all_positions(scene, states, ts)
        dx = np.where(wall[:, None], x[ii], x[ii] - x[jj_safe])
        dy = np.where(wall[:, None], y[ii], y[ii] - y[jj_safe])
        dvx = np.where(wall[:, None], vx[ii], vx[ii] - vx[jj_safe])
        dvy = np.where(wall[:, None], vy[ii], vy[ii] - vy[jj_safe])
        d2 = dx * dx + dy * dy
        sep = np.where(wall[:, None], r0 * r0 - d2, d2 - c2)
        return sep, np.where(wall[:, None], -2.0, 2.0) * (dx * dvx + dy * dvy), dvx * dvx + dvy * dvy

    s0, ds0, _ = pair_arrays(np.array([t_start_s]))
    s_prev, ds_prev = s0[:, 0], ds0[:, 0]
    for idx, (i, j) in enumerate(pairs):
        state = states[i]
        if funcs[idx][0] is not funcs[idx][1] and state.t0_s == t_start_s:  # departing now: the zero-length rule
            assert isinstance(state, FlightState)
            touching = zero_length_departure(scene, state, n_d.get(i, 0.0))
        elif funcs[idx][0] is not funcs[idx][1]:  # left the wall earlier: the gap with its departure root divided out
            touching = funcs[idx][0](t_start_s - t_ref[idx]) <= 0.0
        else:
            touching = s_prev[idx] <= 0.0
        if touching:
            return contact_kinematics(scene, states, i, j, t_start_s, t_start_s - t_ref[idx])
    t_prev = t_start_s
    while t_prev < t_end_s:
        ts = np.minimum(t_prev + h * np.arange(1, _SCAN_SAMPLES + 1), t_end_s)
        sep, dsep, rel_v2 = pair_arrays(ts)
        v2 = np.max(rel_v2, axis=1)
        curvature = 2.0 * ((np.sqrt(v2) + 2.0 * accel * h) ** 2 + 4.0 * r0 * accel)
        margin = (curvature * h * h / 8.0)[:, None]
        s_before = np.concatenate((s_prev[:, None], sep[:, :-1]), axis=1)
        ds_before = np.concatenate((ds_prev[:, None], dsep[:, :-1]), axis=1)
        t_before = np.concatenate(([t_prev], ts[:-1]))
        near_zero = np.abs(sep) < 1e-9 * r0 * r0  # re-evaluate with the stable (reduced) form
        crossing = sep <= 0.0
        minimum = (ds_before < 0.0) & (dsep > 0.0) & (np.minimum(s_before, sep) <= margin)
        candidates = (crossing | minimum | near_zero) & (ts > t_before)[None, :]
        best: tuple[float, int, float] | None = None  # (t, pair, τ)
        for k in sorted(set(np.flatnonzero(candidates.any(axis=0)).tolist())):
            if best is not None and t_before[k] >= best[0]:
                break
            for p in np.flatnonzero(candidates[:, k]):
                ref = t_ref[p]
                tau_hit = _resolve(funcs[p], float(t_before[k]) - ref, float(ts[k]) - ref, tol_s)
                if tau_hit is not None and (best is None or ref + tau_hit < best[0]):
                    best = (ref + tau_hit, int(p), tau_hit)
        if best is not None:
            i, j = pairs[best[1]]
            return contact_kinematics(scene, states, i, j, best[0], best[2])
        t_prev, s_prev, ds_prev = float(ts[-1]), sep[:, -1], dsep[:, -1]
    return None


def _all_positions(scene: Scene, states: list[RodState], ts: np.ndarray) -> tuple[np.ndarray, ...]:
    """(x, y, vx, vy) of every rod at times ts, shape (rods, times); pinned rods in one vectorised pass."""
    x, y, vx, vy = (np.empty((len(states), len(ts))) for _ in range(4))
    pinned = [k for k, st in enumerate(states) if isinstance(st, WallState)]
    if pinned:
        r0 = scene.model.r0_m
        t0 = np.array([states[k].t0_s for k in pinned])
        th0 = np.array([states[k].theta0_rad for k in pinned])  # type: ignore[union-attr]
        w = np.array([states[k].rate_rad_s(scene) for k in pinned])[:, None]  # type: ignore[union-attr]
        theta = th0[:, None] + w * (ts[None, :] - t0[:, None])
        c, sn = np.cos(theta), np.sin(theta)
        x[pinned], y[pinned], vx[pinned], vy[pinned] = r0 * c, r0 * sn, -r0 * w * sn, r0 * w * c
    for k, st in enumerate(states):
        if isinstance(st, FlightState):
            x[k], y[k], vx[k], vy[k] = st.rel_array(scene, ts)
    return x, y, vx, vy


def _pair_functions(
    scene: Scene, states: list[RodState], i: int, j: int, t_start_s: float, n_d_m2_s2: float
) -> tuple[Callable[[float], float], Callable[[float], float], Callable[[float], float]]:
    """(sign function, separation, its derivative) of one pair, all functions of the mover's τ = t − t_0.

    The mover ``i`` is a flying rod; its position comes from its own clock τ and its
    partner's from t_0 + τ. The sign function of a flight that began on the wall divides out
    its departure root, in every search of that flight: a search that restarts (another rod
    detached) a few ns after the departure saw r0² − |d|² at rounding level, of either sign,
    and booked a 1e-9 s micro-hop or not by chance (tests/unit/physics/test_many_event.py).
    """
    a = states[i]
    assert isinstance(a, FlightState)
    flight, t0 = a, a.t0_s
    if j != WALL:
        b = states[j]
        c2 = scene.model.contact_distance_m**2

        def rod_sep(tau: float) -> float:
            xa, ya, _, _ = flight.rel_tau(scene, tau)
            xb, yb, _, _ = b.rel(scene, t0 + tau)
            return (xa - xb) ** 2 + (ya - yb) ** 2 - c2

        def rod_dsep(tau: float) -> float:
            xa, ya, vxa, vya = flight.rel_tau(scene, tau)
            xb, yb, vxb, vyb = b.rel(scene, t0 + tau)
            return 2.0 * ((xa - xb) * (vxa - vxb) + (ya - yb) * (vya - vyb))

        return rod_sep, rod_sep, rod_dsep
    r0sq = scene.model.r0_m**2

    def wall_sep(tau: float) -> float:
        x, y, _, _ = flight.rel_tau(scene, tau)
        return r0sq - (x * x + y * y)

    def wall_dsep(tau: float) -> float:
        x, y, vx, vy = flight.rel_tau(scene, tau)
        return -2.0 * (x * vx + y * vy)

    if flight.from_wall:  # at every τ of its flight, not only in the search that starts at its departure

        def reduced(tau: float) -> float:
            return departure_wall_gap(scene, flight, n_d_m2_s2, tau)

        return reduced, wall_sep, wall_dsep
    return wall_sep, wall_sep, wall_dsep


def _resolve(
    funcs: tuple[Callable[[float], float], Callable[[float], float], Callable[[float], float]],
    a: float,
    b: float,
    tol_s: float = 0.0,
) -> float | None:
    """Exact contact time in [a, b] (the mover's τ) for one candidate interval, or None (a minimum that stays apart)."""
    sign_sep, _, dsep = funcs
    if sign_sep(b) <= 0.0:
        return _root(sign_sep, a, b, tol_s)
    da, db = dsep(a), dsep(b)
    if da < 0.0 < db:
        t_m = _root(dsep, a, b)
        if sign_sep(t_m) <= 0.0:
            return _root(sign_sep, a, t_m, tol_s)
    return None


__all__ = [
    "WALL",
    "Contact",
    "ContactRow",
    "contact_kinematics",
    "earliest_contact",
    "first_contact_time",
    "scan_step_s",
]

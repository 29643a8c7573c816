"""Level (c) compiled: the first contact of any flying rod among all rods (reference: events.earliest_contact).

Every flying rod against the wall and every other rod, bracketed on the reference's grid (1/16 of the shortest
time scale, chunks of :data:`~.many_layout.SCAN_SAMPLES`, the second-order margin over the chunk's largest
relative speed) and resolved by Brent's method in the mover's own clock τ (:mod:`.many_roots`). A held rod
turns at its own rate: ω_r carried, its slide step's mean rate sliding (``_S_DW``, :mod:`.slide`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from millctl.physics.kernels.layout import (
    _G,
    _N,
    _NEAR_ZERO,
    _R0,
    _RD,
    _RR,
    _S_DW,
    _S_FLY,
    _S_T0,
    _S_TH,
    _TWO_PI,
    _WR,
    _WV,
    WALL,
)
from millctl.physics.kernels.many_layout import _B_FROM_WALL, SCAN_SAMPLES
from millctl.physics.kernels.many_roots import _gap_tau, _resolve
from millctl.physics.kernels.motion import _flying_rel, _rel, _zero_length_departure


@njit(cache=True)
def _shortest_time_s(p):  # type: ignore[no-untyped-def]
    """events.shortest_time_s: the shortest of the cam's lift period, the revolution and the fall time √(2 r_r/g)."""
    shortest = math.sqrt(2.0 * p[_RR] / p[_G])
    for w in (p[_WV], p[_WR]):
        if w > 0.0:
            shortest = min(shortest, _TWO_PI / w)
    return shortest


@njit(cache=True)
def _scan_step_s(p):  # type: ignore[no-untyped-def]
    """events.scan_step_s: 1/16 of the shortest time scale (:func:`_shortest_time_s`)."""
    return _shortest_time_s(p) / 16.0


@njit(cache=True)
def _pair_now(p, pos, i, j):  # type: ignore[no-untyped-def]
    """(separation, its derivative, relative speed²) of a pair from the rods' positions (vial frame)."""
    x, y, vx, vy = pos[i, 0], pos[i, 1], pos[i, 2], pos[i, 3]
    if j == WALL:
        return p[_R0] * p[_R0] - (x * x + y * y), -2.0 * (x * vx + y * vy), vx * vx + vy * vy
    dx, dy, dvx, dvy = x - pos[j, 0], y - pos[j, 1], vx - pos[j, 2], vy - pos[j, 3]
    return dx * dx + dy * dy - 4.0 * p[_RR] * p[_RR], 2.0 * (dx * dvx + dy * dvy), dvx * dvx + dvy * dvy


@njit(cache=True)
def _fill(p, st, n, count, pi, pj, pos, ts, sep, dsep, prev, start, stop, turn, h):  # type: ignore[no-untyped-def]
    """Samples start..stop−1 of a chunk: every pair's separation and derivative, the largest relative speed².

    Rods move by phasors (``turn``: the cos, sin of a held rod's angle θ or of a flying rod's cam turn ω_v τ
    at the last filled sample, turned by one step's ω h; the last row the steps' cos ω_r h, sin ω_r h, cos ω_v h,
    sin ω_v h), evaluated afresh at a sample the end clamped: a few ulp from the reference's cos and sin,
    which only decide which intervals are resolved (the roots come from :func:`_g`, exactly).
    """
    cr, sr, cv, sv = turn[n, 0], turn[n, 1], turn[n, 2], turn[n, 3]
    r0 = p[_R0]
    for s_ in range(start, stop):
        t = ts[s_ + 1]
        exact = t != ts[0] + h * (s_ + 1)
        for r in range(n):
            held = st[r, _S_FLY] == 0.0
            w_r = p[_WR] + st[r, _S_DW]  # a held rod's rate: ω_r carried, its slide step's mean rate sliding
            if exact or (held and st[r, _S_DW] != 0.0):
                x = st[r, _S_TH] + w_r * (t - st[r, _S_T0]) if held else p[_WV] * (t - st[r, _S_T0])
                turn[r, 0], turn[r, 1] = math.cos(x), math.sin(x)
            elif held:
                turn[r, 0], turn[r, 1] = turn[r, 0] * cr - turn[r, 1] * sr, turn[r, 1] * cr + turn[r, 0] * sr
            else:
                turn[r, 0], turn[r, 1] = turn[r, 0] * cv - turn[r, 1] * sv, turn[r, 1] * cv + turn[r, 0] * sv
            c, sn = turn[r, 0], turn[r, 1]
            if held:
                pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = r0 * c, r0 * sn, -r0 * w_r * sn, r0 * w_r * c
            else:
                pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = _flying_rel(p, st, r, t - st[r, _S_T0], c, sn)
        for k in range(count):
            s, ds, v2 = _pair_now(p, pos, pi[k], pj[k])
            sep[k, s_], dsep[k, s_] = s, ds
            prev[k, 2] = max(prev[k, 2], v2)
    return stop


@njit(cache=True)
def _earliest(p, st, book, excluded, t_start, t_end, tol, w):  # type: ignore[no-untyped-def]
    """events.earliest_contact: (t, rod, partner, τ) of the first contact of a flying rod in [t_start, t_end]."""
    n = int(p[_N])
    pi, pj, reduced = w[0], w[1], w[2]
    sep, dsep, prev, pos, ts, turn = w[3], w[4], w[5], w[6], w[7], w[8]
    count = 0
    for i in range(n):
        if st[i, _S_FLY] != 0.0:
            pi[count], pj[count] = i, WALL
            reduced[count] = 1 if book[i, _B_FROM_WALL] != 0.0 else 0
            count += 1
    for i in range(n):
        if st[i, _S_FLY] == 0.0:
            continue
        for j in range(n):
            if j == i or (st[j, _S_FLY] != 0.0 and j < i) or excluded[min(i, j), max(i, j)] != 0:
                continue
            pi[count], pj[count], reduced[count] = i, j, 0
            count += 1
    for r in range(n):
        pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = _rel(p, st, r, t_start)
    for k in range(count):
        i, j = pi[k], pj[k]
        s, ds, _ = _pair_now(p, pos, i, j)
        if reduced[k] != 0 and st[i, _S_T0] == t_start:
            touching = _zero_length_departure(p, st, i)
        elif reduced[k] != 0:
            touching = _gap_tau(p, st, i, t_start - st[i, _S_T0]) <= 0.0
        else:
            touching = s <= 0.0
        if touching:
            return t_start, i, j, t_start - st[i, _S_T0]
        prev[k, 0], prev[k, 1] = s, ds
    h = _scan_step_s(p)
    w2 = p[_WR] * p[_WR]
    for r in range(n):
        if st[r, _S_FLY] == 0.0:
            w2 = max(w2, (p[_WR] + st[r, _S_DW]) ** 2)
    accel = 2.0 * max(p[_G] + p[_RD] * p[_WV] * p[_WV], p[_R0] * w2)
    r0 = p[_R0]
    near = _NEAR_ZERO * r0 * r0
    turn[n, 0], turn[n, 1] = math.cos(p[_WR] * h), math.sin(p[_WR] * h)
    turn[n, 2], turn[n, 3] = math.cos(p[_WV] * h), math.sin(p[_WV] * h)
    t_prev = t_start
    while t_prev < t_end:
        ts[0] = t_prev
        for s_ in range(1, SCAN_SAMPLES + 1):
            ts[s_] = min(t_prev + h * s_, t_end)
        for r in range(n):
            held = st[r, _S_FLY] == 0.0
            w_r = p[_WR] + st[r, _S_DW]
            x = st[r, _S_TH] + w_r * (t_prev - st[r, _S_T0]) if held else p[_WV] * (t_prev - st[r, _S_T0])
            turn[r, 0], turn[r, 1] = math.cos(x), math.sin(x)
        for k in range(count):
            prev[k, 2] = 0.0
        # samples are filled as the candidates need them; the margin of a minimum needs the chunk's largest
        # relative speed (the reference's), so the first minimum fills the whole chunk: the same test, lazily
        filled = 0
        best, best_k, best_tau = math.inf, -1, 0.0
        for s_ in range(SCAN_SAMPLES):
            t_a, t_b = ts[s_], ts[s_ + 1]
            if best_k >= 0 and t_a >= best:
                break
            if filled <= s_:
                filled = _fill(p, st, n, count, pi, pj, pos, ts, sep, dsep, prev, filled, s_ + 1, turn, h)
            if not t_b > t_a:
                continue
            for k in range(count):
                s_before = prev[k, 0] if s_ == 0 else sep[k, s_ - 1]
                ds_before = prev[k, 1] if s_ == 0 else dsep[k, s_ - 1]
                s, ds = sep[k, s_], dsep[k, s_]
                hit = s <= 0.0 or abs(s) < near
                if not hit and ds_before < 0.0 < ds:
                    if filled < SCAN_SAMPLES:
                        filled = _fill(
                            p, st, n, count, pi, pj, pos, ts, sep, dsep, prev, filled, SCAN_SAMPLES, turn, h
                        )
                    margin = 2.0 * ((math.sqrt(prev[k, 2]) + 2.0 * accel * h) ** 2 + 4.0 * r0 * accel) * h * h / 8.0
                    hit = min(s_before, s) <= margin
                if not hit:
                    continue
                i, j = pi[k], pj[k]
                ref = st[i, _S_T0]
                tau = _resolve(p, st, i, j, reduced[k] != 0, t_a - ref, t_b - ref, tol)
                if tau < math.inf and ref + tau < best:
                    best, best_k, best_tau = ref + tau, k, tau
        if best_k >= 0:
            return best, pi[best_k], pj[best_k], best_tau
        last = SCAN_SAMPLES - 1
        for k in range(count):
            prev[k, 0], prev[k, 1] = sep[k, last], dsep[k, last]
        t_prev = ts[SCAN_SAMPLES]
    return math.inf, -1, -1, 0.0


@njit(cache=True)
def _work(n):  # type: ignore[no-untyped-def]
    """Work arrays of the contact search for n rods: pair ids, reduced flags, chunk samples, positions, phasors."""
    pairs = n * n + 1
    return (
        np.empty(pairs, dtype=np.int64),
        np.empty(pairs, dtype=np.int64),
        np.empty(pairs, dtype=np.int64),
        np.empty((pairs, SCAN_SAMPLES)),
        np.empty((pairs, SCAN_SAMPLES)),
        np.empty((pairs, 3)),
        np.empty((n, 4)),
        np.empty(SCAN_SAMPLES + 1),
        np.empty((n + 1, 4)),
    )


__all__: list[str] = []

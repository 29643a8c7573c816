"""The first contact of a flying rod with the wall or another rod (the reference is :mod:`millctl.physics.events`).

Eqs 12–17 done exactly: every pair is scanned on a grid (separation, its exact derivative, and the
second-order margin that lets a grazing minimum be skipped only when it provably stays apart, or when the
tangents at the step's ends prove it), held rods turned and flying rods' cam phases advanced by phasors;
a bracketed sign change is resolved by Newton's method kept in its bracket for a rod pair
(:func:`.roots._newton_from`) and by Brent's for the wall, a bracketed minimum by Brent's on the derivative.
"""

from __future__ import annotations

import math

from millctl.physics.kernels.layout import (
    _F_DSEP,
    _F_SIGN_SEP,
    _G,
    _NEAR_ZERO,
    _R0,
    _RD,
    _RESYNC,
    _RR,
    _RTOL,
    _S_FLY,
    _S_PC,
    _S_PS,
    _S_T0,
    _TWO_PI,
    _WR,
    _WV,
    WALL,
    leaf_kernel,
)
from millctl.physics.kernels.motion import _departure_gap, _flying_rel, _pair, _zero_length_departure
from millctl.physics.kernels.roots import _brentq_from, _f, _newton_from, _xtol


@leaf_kernel
def _scan_step_s(p):  # type: ignore[no-untyped-def]
    """1/8 of the shortest of the cam period, the revolution and the fall time √(2 r_r/g).

    The reference (events.scan_step_s) samples at 1/16; the minimum check's margin grows with the step
    (h²/8 × a bound on the separation's second derivative), so either step brackets the same contacts, and the
    coarser one halves the samples (issue 17's throughput; the same answers on 10⁴ random scenes).
    """
    shortest = math.sqrt(2.0 * p[_RR] / p[_G])
    if p[_WV] > 0.0:
        shortest = min(shortest, _TWO_PI / p[_WV])
    if p[_WR] > 0.0:
        shortest = min(shortest, _TWO_PI / p[_WR])
    return shortest / 8.0


@leaf_kernel
def _resolve(p, st, tr, i, j, a, b, tol, s_a, ds_a):  # type: ignore[no-untyped-def]
    """Exact contact time in [a, b] of one candidate interval, or inf (a minimum that stays apart).

    ``s_a``, ``ds_a``: the scan's separation and its slope at a when the separation is certainly positive (≥ the
    scan's near-zero band, far above the phasors' drift), else nan: a rod pair's sign change is then bracketed
    without evaluating a again, and its root finder starts from the cubic through both ends.
    A rod pair's contact is found by Newton's method (its separation's slope comes with it, :func:`_pair`), the
    wall's by Brent's on the departure gap, whose triple root at the departure is divided out.
    """
    if j == WALL:
        f_b = _f(_F_SIGN_SEP, p, st, tr, i, j, b)
        db = math.nan
    else:
        f_b, db, _ = _pair(p, st, i, j, b)
    if f_b <= 0.0:
        if j == WALL:
            f_a = _f(_F_SIGN_SEP, p, st, tr, i, j, a)
            return _brentq_from(_F_SIGN_SEP, p, st, tr, i, j, a, b, f_a, f_b, _xtol(a, b, tol), _RTOL)
        if s_a > 0.0:
            f_a, da = s_a, ds_a
        else:
            f_a, da, _ = _pair(p, st, i, j, a)
        return _newton_from(_F_SIGN_SEP, p, st, tr, i, j, a, b, f_a, da, f_b, db, _xtol(a, b, tol), _RTOL)
    da = _f(_F_DSEP, p, st, tr, i, j, a)
    if j == WALL:
        db = _f(_F_DSEP, p, st, tr, i, j, b)
    if da < 0.0 < db:
        t_m = _brentq_from(_F_DSEP, p, st, tr, i, j, a, b, da, db, _xtol(a, b, 0.0), _RTOL)
        f_m = _f(_F_SIGN_SEP, p, st, tr, i, j, t_m)
        if f_m <= 0.0:
            f_a = _f(_F_SIGN_SEP, p, st, tr, i, j, a)
            return _brentq_from(_F_SIGN_SEP, p, st, tr, i, j, a, t_m, f_a, f_m, _xtol(a, t_m, tol), _RTOL)
    return math.inf


@leaf_kernel
def _tangent_bound(s_a, ds_a, s_b, ds_b, width, curvature):  # type: ignore[no-untyped-def]
    """A lower bound on s over a step of ``width`` from its values and slopes at both ends and |s″| ≤ ``curvature``.

    s(a + u) ≥ P_a(u) = s_a + s′_a u − ½Cu² and s(b − w) ≥ P_b = s_b − s′_b w − ½Cw² (Taylor with the bound on
    s″): s ≥ max(P_a, P_b), two concave parabolas whose difference is linear in u, so the max is least at an end
    of the step or where they cross; with s′_a < 0 < s′_b they cross once.
    """
    crossing = (s_a - s_b + ds_b * width + 0.5 * curvature * width * width) / (ds_b - ds_a + curvature * width)
    bound = min(s_a, s_b)
    if 0.0 < crossing < width:
        bound = min(bound, s_a + ds_a * crossing - 0.5 * curvature * crossing * crossing)
    return bound


@leaf_kernel
def _turned(c, s, c_step, s_step):  # type: ignore[no-untyped-def]
    """cos, sin of φ + δ from those of φ and δ."""
    return c * c_step - s * s_step, s * c_step + c * s_step


@leaf_kernel
def _apart_for(wall, gap, dist, radial, v2, accel_fly, accel_held, st, j):  # type: ignore[no-untyped-def]
    """How long a pair at ``gap`` > 0 provably stays apart (s).

    d: the rod's position (wall) or the pair's relative position, |d| = ``dist``, v = d′, ``radial`` = d̂·v,
    A ≥ |d″| (g + r_d ω_v² for a flying rod in the vial frame, plus r0 ω_r² for a held partner).
    Rod pair: |d + vΔ + R| ≥ d̂·(d + vΔ) − |R| = |d| + Δ·radial − |R|, |R| ≤ ½AΔ², so the gap shrinks by
    at most u Δ + ½AΔ² with u = max(−radial, 0), the approach speed.
    Wall (gap r0 − |d|): |d + vΔ| ≤ |d| + Δ·radial + Δ²|v|²/(2|d|) (√(a² + x) ≤ a + x/2a), so the gap
    shrinks by at most uΔ + ½BΔ² with u = max(radial, 0) and B = A + |v|²/|d|.
    The first Δ at which the bound reaches zero: 2 gap / (u + √(u² + 2 B gap)).
    """
    if wall:
        approach, bound = max(radial, 0.0), accel_fly + v2 / dist
    else:
        approach = max(-radial, 0.0)
        bound = accel_fly + accel_held if st[j, _S_FLY] == 0.0 else 2.0 * accel_fly
    return 2.0 * gap / (approach + math.sqrt(approach * approach + 2.0 * bound * gap))


@leaf_kernel
def _scan_steps(p):  # type: ignore[no-untyped-def]
    """The contact scan's step h (:func:`_scan_step_s`) and the turns of one step, cos, sin of ω_r h and of ω_v h.

    The same for every scan of a scene: :func:`.events._event` takes them once and hands them to each.
    """
    h = _scan_step_s(p)
    return h, math.cos(p[_WR] * h), math.sin(p[_WR] * h), math.cos(p[_WV] * h), math.sin(p[_WV] * h)


@leaf_kernel
def _earliest_contact(p, st, tr, n, t_start, t_end, tol, scratch, steps):  # type: ignore[no-untyped-def]
    """(time, rod, partner) of the first contact of a flying rod in [t_start, t_end]; time inf if none.

    ``steps``: :func:`_scan_steps` of the scene. A held rod's position comes from its state's angle at t = 0
    (``_S_PC``, ``_S_PS``), a flying rod's from eq. 10 (:func:`.motion._flying_rel`).
    """
    pairs, pair_ids, rods, rod_ids = scratch[0], scratch[1], scratch[2], scratch[3]
    pi, pj = pair_ids[:, 0], pair_ids[:, 1]
    count = 0
    for i in range(n):
        if st[i, _S_FLY] != 0.0:
            pi[count], pj[count] = i, WALL
            count += 1
    for i in range(n):
        if st[i, _S_FLY] == 0.0:
            continue
        for j in range(n):
            if j == i or (st[j, _S_FLY] != 0.0 and j < i):
                continue
            pi[count], pj[count] = i, j
            count += 1
    # every rod's vial-frame position at t_start; a held rod's later position is this one turned by ω_r(t − t_start)
    # a held rod's position later is its position at t_start turned by ω_r(t − t_start); a flying rod's needs
    # cos, sin of ω_v(t − t0): both are phasors advanced by one step's turn, recomputed every _RESYNC steps
    pos, phasor = rods[:, 0:4], rods[:, 4:6]
    w_r, r0 = p[_WR], p[_R0]
    cos_start, sin_start = math.cos(w_r * t_start), math.sin(w_r * t_start)
    for r in range(n):
        if st[r, _S_FLY] == 0.0:  # its angle at t = 0 turned by ω_r t_start: one sine and cosine for every held rod
            xh, yh = _turned(r0 * st[r, _S_PC], r0 * st[r, _S_PS], cos_start, sin_start)
            pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = xh, yh, -w_r * yh, w_r * xh
            phasor[r, 0], phasor[r, 1] = xh, yh
        else:  # the cam's turn since departure, cos and sin, is the flying rod's phasor
            tau = t_start - st[r, _S_T0]
            phasor[r, 0], phasor[r, 1] = math.cos(p[_WV] * tau), math.sin(p[_WV] * tau)
            pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = _flying_rel(p, st, r, tau, phasor[r, 0], phasor[r, 1])
    c2 = 4.0 * p[_RR] * p[_RR]
    s_prev, ds_prev, v2_prev, safe_until, stale = pairs[:, 0], pairs[:, 1], pairs[:, 2], pairs[:, 3], pairs[:, 4]
    for k in range(count):
        i, j = pi[k], pj[k]
        x, y, vx, vy = pos[i, 0], pos[i, 1], pos[i, 2], pos[i, 3]
        if j == WALL:
            s, ds = r0 * r0 - (x * x + y * y), -2.0 * (x * vx + y * vy)
            if t_start == st[i, _S_T0]:
                touching = _zero_length_departure(p, st, i)
            else:
                touching = _departure_gap(p, st, i, t_start) <= 0.0
        else:
            x, y, vx, vy = x - pos[j, 0], y - pos[j, 1], vx - pos[j, 2], vy - pos[j, 3]
            s, ds = x * x + y * y - c2, 2.0 * (x * vx + y * vy)
            touching = s <= 0.0
        if touching:
            return t_start, i, j
        s_prev[k], ds_prev[k], v2_prev[k] = s, ds, vx * vx + vy * vy
    h, cos_step_r, sin_step_r, cos_step_v, sin_step_v = steps
    accel = 2.0 * max(p[_G] + p[_RD] * p[_WV] * p[_WV], p[_R0] * p[_WR] * p[_WR])
    # bounds on the relative acceleration of a pair in the vial frame (the wall is at rest there)
    accel_fly, accel_held = p[_G] + p[_RD] * p[_WV] * p[_WV], p[_R0] * p[_WR] * p[_WR]
    near = _NEAR_ZERO * r0 * r0
    w_v = p[_WV]
    cos_turn, sin_turn = 1.0, 0.0
    safe_until[:count] = t_start
    stale[:count] = 0.0
    filled_at = rod_ids
    filled_at[:n] = 0
    t_prev = t_start
    step = 0
    while t_prev < t_end:
        step += 1
        t_k = min(t_start + h * step, t_end)
        t_next = min(t_start + h * (step + 1), t_end)
        exact = step % _RESYNC == 0 or t_k == t_end
        if exact:
            cos_turn, sin_turn = math.cos(w_r * (t_k - t_start)), math.sin(w_r * (t_k - t_start))
        else:
            cos_turn, sin_turn = _turned(cos_turn, sin_turn, cos_step_r, sin_step_r)
        for r in range(n):
            if st[r, _S_FLY] == 0.0:
                continue
            if exact:
                x = w_v * (t_k - st[r, _S_T0])
                phasor[r, 0], phasor[r, 1] = math.cos(x), math.sin(x)
            else:
                phasor[r, 0], phasor[r, 1] = _turned(phasor[r, 0], phasor[r, 1], cos_step_v, sin_step_v)
        best, best_k, best_exact = math.inf, -1, False
        for k in range(count):
            if t_next <= safe_until[k] and t_k < t_end:
                stale[k] = 1.0  # provably apart up to the next sample: not evaluated
                continue
            i, j = pi[k], pj[k]
            for r in (i, j):
                if r == WALL or filled_at[r] == step:
                    continue
                filled_at[r] = step
                if st[r, _S_FLY] != 0.0:
                    pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = _flying_rel(
                        p, st, r, t_k - st[r, _S_T0], phasor[r, 0], phasor[r, 1]
                    )
                    continue
                xh = phasor[r, 0] * cos_turn - phasor[r, 1] * sin_turn
                yh = phasor[r, 0] * sin_turn + phasor[r, 1] * cos_turn
                pos[r, 0], pos[r, 1], pos[r, 2], pos[r, 3] = xh, yh, -w_r * yh, w_r * xh
            x, y, vx, vy = pos[i, 0], pos[i, 1], pos[i, 2], pos[i, 3]
            if j == WALL:
                s, ds = r0 * r0 - (x * x + y * y), -2.0 * (x * vx + y * vy)
                dist = math.sqrt(max(x * x + y * y, 0.0))
                gap = r0 - dist
            else:
                x, y, vx, vy = x - pos[j, 0], y - pos[j, 1], vx - pos[j, 2], vy - pos[j, 3]
                s, ds = x * x + y * y - c2, 2.0 * (x * vx + y * vy)
                dist = math.sqrt(x * x + y * y)
                gap = dist - 2.0 * p[_RR]
            v2 = vx * vx + vy * vy
            if stale[k] != 0.0:
                stale[k] = 0.0  # the interval since the last sample lies where the pair is provably apart
            else:
                hit = s <= 0.0 or abs(s) < near
                if not hit and ds_prev[k] < 0.0 < ds:  # a minimum in the step: may it reach zero?
                    v = math.sqrt(max(v2, v2_prev[k]))
                    curvature = 2.0 * ((v + 2.0 * accel * h) ** 2 + 4.0 * r0 * accel)  # ≥ |s″| on the step
                    if min(s_prev[k], s) <= curvature * h * h / 8.0:
                        # resolved unless the tangents at the step's ends prove the pair apart
                        hit = _tangent_bound(s_prev[k], ds_prev[k], s, ds, t_k - t_prev, curvature) <= near
                if hit and t_k > t_prev:
                    s_a, ds_a = (s_prev[k], ds_prev[k]) if s_prev[k] >= near else (math.nan, math.nan)
                    t_hit = _resolve(p, st, tr, i, j, t_prev, t_k, tol, s_a, ds_a)
                    if tol > 0.0 and best_k >= 0 and abs(t_hit - best) <= 2.0 * tol:
                        # two contacts closer than the tolerance: which is first is decided at full precision
                        t_hit = _resolve(p, st, tr, i, j, t_prev, t_k, 0.0, s_a, ds_a)
                        if not best_exact:
                            pair_i, pair_j = pi[best_k], pj[best_k]
                            best = _resolve(p, st, tr, pair_i, pair_j, t_prev, t_k, 0.0, math.nan, math.nan)
                            best_exact = True
                    elif t_hit < best:
                        best_exact = False
                    if t_hit < best:
                        best, best_k = t_hit, k
            s_prev[k], ds_prev[k], v2_prev[k] = s, ds, v2
            if gap > 0.0 and dist > 0.0:
                radial = (x * vx + y * vy) / dist
                safe_until[k] = t_k + _apart_for(j == WALL, gap, dist, radial, v2, accel_fly, accel_held, st, j)
        if best_k >= 0:
            return best, pi[best_k], pj[best_k]
        t_prev = t_k
    return math.inf, -1, -1

"""The event loop up to the first impact (the reference is :mod:`millctl.physics.simulate` with stop_after_first).

Every rod starts pinned at eq. 11's angle; rods detach at their own times (``rods="all"``) or only
rod 0 does, the others held (``rods="one"``). The first contact ends the loop: its kinematics and
energy (eq. 19, printed ½ m |v|² or corrected ½ m_eff (1 − e²) v_n²) fill a result row (:data:`OUT`).
A zero-length flight (the package docstring) is no impact. :func:`first_impacts` is the batch entry point.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from millctl.physics.kernels.contacts import _earliest_contact, _scan_steps
from millctl.physics.kernels.detach import _falling_zero_windowed, _never_detaches, _rearm, _revolution_s, _window_s
from millctl.physics.kernels.layout import (
    _A0,
    _E,
    _G,
    _L,
    _M,
    _N,
    _O_ALD,
    _O_BACKED,
    _O_ENERGY,
    _O_FOUND,
    _O_PARTNER,
    _O_ROD,
    _O_SPEED,
    _O_T,
    _O_TD0,
    _O_TDEP,
    _O_THC,
    _O_THD,
    _O_VN,
    _O_VT,
    _O_X,
    _O_Y,
    _O_ZERO,
    _PAPER,
    _R0,
    _RD,
    _RR,
    _S_CA,
    _S_FLY,
    _S_ND,
    _S_PC,
    _S_PS,
    _S_SA,
    _S_T0,
    _S_TH,
    _S_UX,
    _S_UY,
    _S_X,
    _S_Y,
    _STATE_COLUMNS,
    _T_KAPPA,
    _TA,
    _TH0,
    _TRIG_COLUMNS,
    _TWO_PI,
    _WR,
    _WV,
    OUT,
    PARAMS,
    WALL,
    FloatArray,
    leaf_kernel,
)
from millctl.physics.kernels.motion import _rel
from millctl.physics.kernels.trig import _fill_first_trig_rows

_GAP_TURNS = np.array([[math.cos(2.0 * math.pi / n), math.sin(2.0 * math.pi / n)] for n in range(1, 65)])
"""cos, sin of 2π/n, the angle between neighbouring rods, for n = 1 … 64 (row n − 1)."""


@leaf_kernel
def _gap_turn(n):  # type: ignore[no-untyped-def]
    """cos, sin of 2π/n: from :data:`_GAP_TURNS` up to 64 rods, else computed."""
    if 1 <= n <= _GAP_TURNS.shape[0]:
        return _GAP_TURNS[n - 1, 0], _GAP_TURNS[n - 1, 1]
    return math.cos(2.0 * math.pi / n), math.sin(2.0 * math.pi / n)


@leaf_kernel
def _depart(p, st, tr, i, t, unsupported):  # type: ignore[no-untyped-def]
    """Rod i leaves the wall at t: its flight state (eq. 2's velocity relative to the vial) and n_d.

    Corrected variant at a falling zero of N: n_d = 0 exactly (the departure root is triple by construction);
    a rod that starts unsupported (N < 0 at the start) or the paper's law: n_d = r0·N_true/m.
    """
    x, y, vx, vy = _rel(p, st, i, t)
    st[i, _S_FLY], st[i, _S_T0] = 1.0, t
    st[i, _S_X], st[i, _S_Y], st[i, _S_UX], st[i, _S_UY] = x, y, vx, vy
    alpha = p[_A0] + p[_WV] * t
    st[i, _S_SA], st[i, _S_CA] = math.sin(alpha), math.cos(alpha)
    g_eff = p[_G] - p[_RD] * p[_WV] ** 2 * st[i, _S_SA]
    true_n = p[_R0] * p[_WR] ** 2 - g_eff * y / p[_R0]  # sin θ of the held rod at (x, y) = r0 (cos θ, sin θ)
    exact = p[_PAPER] == 0.0 and not unsupported
    st[i, _S_ND] = 0.0 if exact else p[_R0] * true_n


@leaf_kernel
def _pin(p, st, i, t, theta):  # type: ignore[no-untyped-def]
    """Rod i held on the wall at angle θ at time t (its state's angle at t = 0 too, for the contact scan)."""
    st[i, _S_FLY], st[i, _S_T0], st[i, _S_TH] = 0.0, t, theta
    st[i, _S_PC], st[i, _S_PS] = math.cos(theta - p[_WR] * t), math.sin(theta - p[_WR] * t)


@leaf_kernel
def _repin(p, st, i, t):  # type: ignore[no-untyped-def]
    x, y, _, _ = _rel(p, st, i, t)
    _pin(p, st, i, t, math.atan2(y, x))


@leaf_kernel
def _scratch_bounds(n_max):  # type: ignore[no-untyped-def]
    """Where :func:`_scratch_in`'s work arrays for n_max rods lie in their buffer: (pairs, b, c, d, e, f, g, end)."""
    pairs = n_max * (n_max + 1)
    b = pairs * 5
    c = b + pairs * 2
    d = c + n_max * 6
    e = d + n_max
    f = e + n_max * _TRIG_COLUMNS
    g = f + n_max * _STATE_COLUMNS
    return pairs, b, c, d, e, f, g, g + n_max * 3


@leaf_kernel
def _scratch_len(n_max):  # type: ignore[no-untyped-def]
    """Length of the one float64 buffer that holds :func:`_scratch_in`'s work arrays for up to n_max rods."""
    return _scratch_bounds(n_max)[7]


@njit(cache=True, error_model="numpy", _nrt=True)  # type: ignore[call-overload]
def _scratch_in(buf, n_max):  # type: ignore[no-untyped-def]
    """Work arrays of _event for up to n_max rods as views of one buffer (:func:`_scratch_len` long).

    (pair columns, pair rod ids, rod columns, rod ids, trig rows, rod states, rod detachment columns);
    the id arrays are int64 views of the buffer's float64 words. No allocation. Reference counted, and
    explicitly so (a kernel without the option set is compiled with its first caller's): for counting
    callers; a leaf kernel takes the same views from :func:`_scratch_views`.
    """
    pairs, b, c, d, e, f, g, end = _scratch_bounds(n_max)
    ids = buf[b:c].view(np.int64).reshape((pairs, 2))
    rods = buf[c:d].reshape((n_max, 6))
    trig = buf[e:f].reshape((n_max, _TRIG_COLUMNS))
    states = buf[f:g].reshape((n_max, _STATE_COLUMNS))
    return (
        buf[:b].reshape((pairs, 5)),
        ids,
        rods,
        buf[d:e].view(np.int64),
        trig,
        states,
        buf[g:end].reshape((n_max, 3)),
    )


@leaf_kernel
def _scratch_views(buf, n_max):  # type: ignore[no-untyped-def]
    """:func:`_scratch_in`'s views for a leaf kernel (uncounted: they must not reach a counting kernel).

    The single-scene call paths (:class:`SceneCall`, :class:`EventCall`) keep one buffer and take these per call.
    """
    pairs, b, c, d, e, f, g, end = _scratch_bounds(n_max)
    ids = buf[b:c].view(np.int64).reshape((pairs, 2))
    rods = buf[c:d].reshape((n_max, 6))
    trig = buf[e:f].reshape((n_max, _TRIG_COLUMNS))
    states = buf[f:g].reshape((n_max, _STATE_COLUMNS))
    return (
        buf[:b].reshape((pairs, 5)),
        ids,
        rods,
        buf[d:e].view(np.int64),
        trig,
        states,
        buf[g:end].reshape((n_max, 3)),
    )


@njit(cache=True, error_model="numpy")
def _scratch(n_max):  # type: ignore[no-untyped-def]
    """Work arrays of _event for up to n_max rods, made once per batch (no allocation per scene).

    (pair columns, pair rod ids, rod columns, rod ids, trig rows, rod states, rod detachment columns)
    """
    return _scratch_in(np.zeros(_scratch_len(n_max)), n_max)


@leaf_kernel
def _event(p, all_rods, horizon, flight_cap, tol, out, scratch):  # type: ignore[no-untyped-def]
    """The first impact of one scene into ``out`` (:data:`OUT`); see the module docstring.

    ``scratch``: :func:`_scratch` for at least this scene's number of rods.
    """
    n = int(p[_N])
    tr = scratch[4][:n]
    detaching = n if all_rods else 1  # rods="one": only rod 0 may leave the wall, only its N row is read
    _fill_first_trig_rows(p, n, detaching, tr)
    st = scratch[5][:n]
    st[:, :] = 0.0
    det_columns = scratch[6]
    det_t, det_lb, unsupported = det_columns[:n, 0], det_columns[:n, 1], det_columns[:n, 2]
    det_t[:] = math.inf
    det_lb[:] = horizon
    unsupported[:] = 0.0
    window = _window_s(p)
    # rod i pinned at θ0 + 2πi/n; cos, sin of its angle by turning rod i − 1's by 2π/n (a few ulp, the scan's and
    # N(0)'s only; rod 0's are the sine and cosine of θ0 itself)
    c_th, s_th = math.cos(p[_TH0]), math.sin(p[_TH0])
    c_gap, s_gap = _gap_turn(n)
    g_eff0 = tr[0, _TA] - tr[0, _T_KAPPA] * math.sin(p[_A0])  # eq. 7's g − κ sin α at t = 0, every rod's
    for i in range(n):
        st[i, _S_FLY], st[i, _S_T0], st[i, _S_TH] = 0.0, 0.0, p[_TH0] + i * 2.0 * math.pi / n
        st[i, _S_PC], st[i, _S_PS] = c_th, s_th
        s_pin = s_th
        c_th, s_th = c_th * c_gap - s_th * s_gap, s_th * c_gap + c_th * s_gap
        if i >= detaching:
            continue
        n_at_start = tr[i, 0] - g_eff0 * s_pin  # N(0)/m in eq. 7's form (:func:`.trig._n_form01` at t = 0)
        if n_at_start <= 0.0:
            det_t[i] = 0.0
            unsupported[i] = 1.0
        elif not _never_detaches(tr, i):
            det_lb[i] = 0.0
    det_end = horizon if all_rods else min(horizon, _revolution_s(p))
    out[:] = math.nan
    out[_O_FOUND], out[_O_ZERO] = 0.0, 0.0
    t = 0.0
    first_departure = math.inf
    steps = _scan_steps(p)
    while True:
        # the earliest known detachment, and the earliest end of a detachment search not yet extended
        t_det, rod_det = math.inf, -1
        lb, rod_lb = math.inf, -1
        t_fly = math.inf
        for i in range(n):
            if det_t[i] < t_det:
                t_det, rod_det = det_t[i], i
            if det_t[i] == math.inf and det_lb[i] < min(det_end, lb):
                lb, rod_lb = det_lb[i], i
            if st[i, _S_FLY] != 0.0:
                t_fly = min(t_fly, st[i, _S_T0])
        contact_end = min(horizon, t_fly + flight_cap)
        seg_end = min(t_det, lb, contact_end)
        t_hit, rod, partner = math.inf, -1, -1
        if t_fly < math.inf:
            t_hit, rod, partner = _earliest_contact(p, st, tr, n, t, seg_end, tol, scratch, steps)
        if t_hit < math.inf:
            if partner == WALL and t_hit == st[rod, _S_T0]:
                # a zero-length flight is no impact: the rod stays held through this dip of N
                _repin(p, st, rod, t_hit)
                out[_O_ZERO] += 1.0
                up = _rearm(p, st, tr, rod, t_hit, det_end)
                det_t[rod] = _falling_zero_windowed(p, st, tr, rod, 1.0, up, det_end) if up < det_end else math.inf
                det_lb[rod] = det_end
                t = t_hit
                continue
            _contact(p, st, rod, partner, t_hit, out)
            out[_O_TD0] = first_departure if first_departure < math.inf else math.nan
            return
        if seg_end >= contact_end and contact_end < min(t_det, lb):
            out[_O_TD0] = first_departure if first_departure < math.inf else math.nan
            return
        if lb <= t_det and rod_lb >= 0:
            a = det_lb[rod_lb]
            b = min(a + window, det_end)
            det_t[rod_lb] = _falling_zero_windowed(p, st, tr, rod_lb, 1.0, a, b)
            det_lb[rod_lb] = b
            t = max(t, a)
            continue
        if rod_det < 0:
            out[_O_TD0] = first_departure if first_departure < math.inf else math.nan
            return
        _depart(p, st, tr, rod_det, t_det, unsupported[rod_det] != 0.0)
        unsupported[rod_det] = 0.0
        first_departure = min(first_departure, t_det)
        det_t[rod_det] = math.inf
        det_lb[rod_det] = det_end
        t = t_det


@leaf_kernel
def _contact(p, st, i, j, t, out):  # type: ignore[no-untyped-def]
    """Contact kinematics, lab contact point, absolute speed and energy (events.contact_kinematics, eq. 19)."""
    x, y, vx, vy = _rel(p, st, i, t)
    if j == WALL:
        r = math.hypot(x, y)
        nx, ny = x / r, y / r
        rvx, rvy = vx + p[_WR] * y, vy - p[_WR] * x
        backed = True
    else:
        xb, yb, vxb, vyb = _rel(p, st, j, t)
        dx, dy = xb - x, yb - y
        r = math.hypot(dx, dy)
        nx, ny = dx / r, dy / r
        rvx, rvy = vx - vxb, vy - vyb
        backed = st[j, _S_FLY] == 0.0
    v_n = rvx * nx + rvy * ny
    alpha = p[_A0] + p[_WV] * t
    yc = p[_L] - p[_RD] + p[_RD] * math.sin(alpha)
    vyc = p[_RD] * p[_WV] * math.cos(alpha)
    speed = math.hypot(vx, vy + vyc)
    m = p[_M]
    if p[_PAPER] != 0.0:
        energy = 0.5 * m * speed * speed
    else:
        energy = 0.5 * (m if backed else 0.5 * m) * (1.0 - p[_E] ** 2) * v_n * v_n
    out[_O_FOUND], out[_O_T], out[_O_ROD], out[_O_PARTNER] = 1.0, t, i, j
    out[_O_X], out[_O_Y] = x + p[_RR] * nx, yc + y + p[_RR] * ny
    out[_O_VN], out[_O_VT] = v_n, -rvx * ny + rvy * nx
    out[_O_SPEED], out[_O_ENERGY], out[_O_BACKED] = speed, energy, 1.0 if backed else 0.0
    t0 = st[i, _S_T0]
    out[_O_TDEP] = t0
    out[_O_THD] = math.atan2(st[i, _S_Y], st[i, _S_X])
    out[_O_THC] = math.atan2(y, x)
    out[_O_ALD] = (p[_A0] + p[_WV] * t0) % _TWO_PI


@njit(cache=True, error_model="numpy")
def _batch(rows, all_rods, horizon, flight_cap, tol):  # type: ignore[no-untyped-def]
    out = np.empty((rows.shape[0], len(OUT)))
    scratch = _scratch(int(rows[:, _N].max()) if rows.shape[0] > 0 else 1)
    for k in range(rows.shape[0]):
        _event(rows[k], all_rods, horizon, flight_cap, tol, out[k], scratch)
    return out


@leaf_kernel
def _scene_event(model_row, omega_r, lift_omega, theta0, lift_alpha0, all_rods, horizon, flight_cap, tol, out, buf):  # type: ignore[no-untyped-def]
    """One scene's first impact into ``out``: ``model_row`` with the scene's speeds and phases, on ``buf``'s views.

    ``buf``: :func:`_scratch_len` (of ``model_row``'s rods) + len(PARAMS) float64 words, its tail the scene row.
    """
    n = int(model_row[_N])
    size = _scratch_len(n)
    p = buf[size : size + len(PARAMS)]
    for k in range(len(PARAMS)):  # not p[:] = model_row: an array copy needs reference counting
        p[k] = model_row[k]
    p[_WR], p[_WV], p[_TH0], p[_A0] = omega_r, lift_omega, theta0, lift_alpha0
    _event(p, all_rods, horizon, flight_cap, tol, out, _scratch_views(buf[:size], n))


_PREPARED_HEAD = ("rods", "all_rods", "horizon_s", "flight_cap_s", "tol_s", "lift_strokes")
"""The first words of a prepared call's buffer (:func:`_prepared_event`): its settings; then the scene row
(:data:`PARAMS`), the result row (:data:`OUT`) and the work arrays (:func:`_scratch_len`)."""


(_H_RODS, _H_ALL, _H_HORIZON, _H_CAP, _H_TOL, _H_LIFT) = range(len(_PREPARED_HEAD))


@leaf_kernel
def _prepared_event(buf, omega_r, omega_v, theta0, alpha0):  # type: ignore[no-untyped-def]
    """One scene's first impact on a prepared buffer (:data:`_PREPARED_HEAD`); True if it found one.

    The scene: the cam motor's ω_r, ω_v (rad/s), θ0, α0 (rad); the result row is left in ``buf``.
    """
    n = int(buf[_H_RODS])
    head = len(_PREPARED_HEAD)
    p = buf[head : head + len(PARAMS)]
    out = buf[head + len(PARAMS) : head + len(PARAMS) + len(OUT)]
    lift = buf[_H_LIFT]
    p[_WR], p[_WV], p[_TH0], p[_A0] = omega_r, lift * omega_v, theta0, lift * alpha0
    work = buf[head + len(PARAMS) + len(OUT) :]
    _event(p, buf[_H_ALL] != 0.0, buf[_H_HORIZON], buf[_H_CAP], buf[_H_TOL], out, _scratch_views(work, n))
    return out[_O_FOUND] == 1.0


def first_impacts(
    rows: FloatArray,
    *,
    rods: str = "all",
    horizon_s: float = 5.0,
    flight_cap_s: float = math.inf,
    tol_s: float = 0.0,
) -> FloatArray:
    """The batch entry point: the first impact of every scene row, one result row each (:data:`OUT` columns).

    ``rows``: shape (scenes, len(PARAMS)) (:func:`scene_row`, :func:`scene_rows`).
    ``rods``: ``"all"`` — every rod detaches at its own time (the same question as
    ``methods.first_impact(scene, "exact")``); ``"one"`` — only rod 0 detaches, within
    one revolution, the others are held on the wall (the node telemetry's sample).
    ``horizon_s``: last time searched (s); ``flight_cap_s``: longest flight followed (s);
    ``tol_s``: root finder's time tolerance (s; 0 ≈ 4 ulp). One core, scenes in order.
    """
    if rods not in ("all", "one"):
        raise ValueError(f"rods = {rods!r}: choose 'all' or 'one'")
    table = np.ascontiguousarray(rows, dtype=np.float64)
    if table.ndim != 2 or table.shape[1] != len(PARAMS):
        columns = ", ".join(PARAMS)
        raise ValueError(f"rows must have shape (scenes, {len(PARAMS)}) (columns: {columns}), got {table.shape}")
    result: FloatArray = _batch(table, rods == "all", float(horizon_s), float(flight_cap_s), float(tol_s))
    return result


__all__ = ["first_impacts"]

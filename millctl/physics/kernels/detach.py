"""Detachment: the certified first falling zero of N(t)/m (eqs 4–7; the reference is :mod:`millctl.physics.detachment`).

A Taylor bound skips the cells where N provably stays positive, critical points split the rest into
monotone pieces, Newton's method kept in its bracket finds the root (N′ comes with N; :mod:`.roots`);
searched one window (the shorter of a revolution and a cam period) at a time, from where N can first
vanish (:func:`_held_until`, :func:`_product_until`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from millctl.physics.kernels.layout import (
    _F_DN,
    _F_N,
    _F_NEG_DN,
    _F_NEG_N,
    _FORM_MARGIN,
    _FORM_N,
    _MAX_DEPTH,
    _N,
    _RTOL,
    _STATE_COLUMNS,
    _T_COUNT,
    _T_G,
    _T_KAPPA,
    _T_N_FORM,
    _T_TH0,
    _T_U,
    _T_V,
    _TA,
    _TP,
    _TW,
    _TWO_PI,
    _WR,
    _WV,
    FloatArray,
    leaf_kernel,
)
from millctl.physics.kernels.roots import _brentq, _newton_from, _xtol
from millctl.physics.kernels.trig import _trig, _trig012, _trig_bound, _trig_rows


@leaf_kernel
def _monotone_pieces_root(p, st, tr, i, sign, a, b):  # type: ignore[no-untyped-def]
    """On [a, b] f' is monotone: split at f's critical point and look for a falling zero (inf: none)."""
    f_code, df_code = (_F_N, _F_DN) if sign > 0.0 else (_F_NEG_N, _F_NEG_DN)
    fa, d1a, _ = _trig012(tr, i, a, sign)
    fb, d1b, _ = _trig012(tr, i, b, sign)
    if fa > 0.0 and fb < 0.0:  # f' monotone: exactly one falling zero in [a, b], no need for the critical point
        return _newton_from(f_code, p, st, tr, i, 0, a, b, fa, d1a, fb, d1b, _xtol(a, b, 0.0), _RTOL)
    if fa > 0.0 and fb > 0.0 and d1a < 0.0 < d1b:
        # convex here: f lies above both end tangents; where they cross is a lower bound on min f
        t_x = (fb - fa + d1a * a - d1b * b) / (d1a - d1b)
        if fa + d1a * (t_x - a) > 1e-13 * (tr[i, 0] + _trig_bound(tr, i, 0)):
            return math.inf
    split = b  # f's critical point when f' changes sign in [a, b]: the two pieces [a, split], [split, b]
    if (d1a < 0.0 < d1b) or (d1a > 0.0 > d1b):
        split = _brentq(df_code, p, st, tr, i, 0, a, b, _xtol(a, b, 0.0), _RTOL)
    # f and f′ at the pieces' ends: fa, fb are _trig012's values there, bit for bit those of _trig (order 0)
    f_split, d_split = fb, d1b
    if split == a:
        f_split, d_split = fa, d1a
    elif split != b:
        f_split, d_split = _trig(tr, i, split, 0, sign), 0.0  # f′ = 0 at the critical point, to its root's rounding
    for s, e, fs, ds, fe, de in ((a, split, fa, d1a, f_split, d_split), (split, b, f_split, d_split, fb, d1b)):
        if s >= e:
            continue
        if fs > 0.0 and fe < 0.0:
            return _newton_from(f_code, p, st, tr, i, 0, s, e, fs, ds, fe, de, _xtol(s, e, 0.0), _RTOL)
        if fs > 0.0 and fe == 0.0 and _trig(tr, i, e, 1, sign) < 0.0:
            return e
    return math.inf


_CELL_POSITIVE, _CELL_MONOTONE, _CELL_SPLIT = 0, 1, 2
"""What :func:`_cell_test` finds of a cell."""


_SPLIT_DEPTH = min(_MAX_DEPTH, 62)
"""The subdivision's depth limit: the reference's (80) where an int64 can index a cell's halves (62).

A cell 2⁻⁶² of a window wide is below the resolution of its time everywhere but within ~10⁻⁵ s of t = 0,
and at the limit the cell is searched whole (:func:`_cell_test`), as at the reference's limit."""


@leaf_kernel
def _falling_zero(p, st, tr, i, sign, t0, t1):  # type: ignore[no-untyped-def]
    """First t in (t0, t1] where sign·N falls through zero, given sign·N(t0) > 0; inf if it stays ≥ 0.

    Each cell is tested whole first (:func:`_cell_test`); only a cell that needs splitting pays for the
    subdivision (:func:`_split_cell`).
    """
    m2, m3 = _trig_bound(tr, i, 2), _trig_bound(tr, i, 3)
    w_max = 0.0
    for k in range(int(tr[i, _T_COUNT])):
        if tr[i, _TA + k] != 0.0:
            w_max = max(w_max, abs(tr[i, _TW + k]))
    cells = 1 if w_max == 0.0 else int(min(max(math.ceil((t1 - t0) * w_max * 2.0 / math.pi), 1), 4096))
    width = (t1 - t0) / cells
    for c in range(cells):
        a = t0 + c * width
        b = t1 if c == cells - 1 else t0 + (c + 1) * width
        verdict = _cell_test(tr, i, sign, a, b, 0, m2, m3)
        if verdict == _CELL_POSITIVE:
            continue
        root = (
            _monotone_pieces_root(p, st, tr, i, sign, a, b)
            if verdict == _CELL_MONOTONE
            else _split_cell(p, st, tr, i, sign, a, b, m2, m3)
        )
        if root < math.inf:
            return root
    return math.inf


@leaf_kernel
def _cell_test(tr, i, sign, a, b, depth, m2, m3):  # type: ignore[no-untyped-def]
    """[a, b] at this depth: certified positive (Taylor bound), searched whole (f″ of one sign, or deep), or split."""
    h = b - a
    f0, f1, f2 = _trig012(tr, i, 0.5 * (a + b), sign)
    linear = f0 - abs(f1) * 0.5 * h
    # Taylor about the midpoint, |u| ≤ h/2: f ≥ f0 − |f′|h/2 − max|f″| h²/8, or with f″ there and max|f‴|:
    # f ≥ f0 − |f′|h/2 + min(f″, 0) h²/8 − max|f‴| h³/48; either bound above zero certifies the cell
    if linear - m2 * h * h * 0.125 > 0.0 or linear + min(f2, 0.0) * h * h * 0.125 - m3 * h * h * h / 48.0 > 0.0:
        return _CELL_POSITIVE
    if abs(f2) > m3 * 0.5 * h or depth >= _SPLIT_DEPTH:
        return _CELL_MONOTONE
    return _CELL_SPLIT


@leaf_kernel
def _split_cell(p, st, tr, i, sign, a, b, m2, m3):  # type: ignore[no-untyped-def]
    """The first falling zero in a cell that needs splitting: bisection, leftmost half first; inf if none.

    The halves are walked as the nodes (depth d, index k) of their binary tree, [a + (b − a)·k/2^d, the next
    node's start] (the last one ends at b), so no stack is needed (a leaf kernel makes no array) and
    neighbours, parents and children share their end points exactly.
    """
    width = b - a
    depth, k = 1, 0
    while True:
        s = a + width * math.ldexp(float(k), -depth)
        e = b if k + 1 == 1 << depth else a + width * math.ldexp(float(k + 1), -depth)
        verdict = _cell_test(tr, i, sign, s, e, depth, m2, m3)
        if verdict == _CELL_SPLIT:
            depth, k = depth + 1, 2 * k  # its left half next
            continue
        if verdict == _CELL_MONOTONE:
            root = _monotone_pieces_root(p, st, tr, i, sign, s, e)
            if root < math.inf:
                return root
        while depth > 0 and k % 2 == 1:  # a right half done: so is its parent
            depth, k = depth - 1, k // 2
        if depth == 0:
            return math.inf
        k += 1  # a left half done: its right sibling next


@leaf_kernel
def _revolution_s(p):  # type: ignore[no-untyped-def]
    """One revolution; one cam period with the vial at rest; 1 s when both stand still."""
    if p[_WR] > 0.0:
        return _TWO_PI / p[_WR]
    if p[_WV] > 0.0:
        return _TWO_PI / p[_WV]
    return 1.0


@leaf_kernel
def _window_s(p):  # type: ignore[no-untyped-def]
    """The detachment search's window: the shorter of one revolution and one cam period."""
    w = _revolution_s(p)
    if p[_WV] > 0.0:
        w = min(w, _TWO_PI / p[_WV])
    return w


@leaf_kernel
def _held_edge(tr, i):  # type: ignore[no-untyped-def]
    """Half-width (rad of the first term's phase) of the arc where row i's first term alone keeps it > 0.

    f = c + a_0 cos(w_0 t + φ_0) + (other terms, ≤ Σ|a_k| together) > 0 while
    cos(w_0 t + φ_0) > q = (Σ_{k≥1}|a_k| − c)/a_0: the arc |w_0 t + φ_0| < acos q (mod 2π). For N/m,
    a_0 cos(…) = g cos(θ + π/2) is the slow part, so this is the arc of the wall where no cam phase can detach
    the rod. −1: no such arc; inf: every time.
    """
    w, g = tr[i, _TW], tr[i, _TA]
    if w <= 0.0 or g <= 0.0:
        return -1.0
    rest = 0.0
    for k in range(1, int(tr[i, _T_COUNT])):
        rest += abs(tr[i, _TA + k])
    q = (rest - tr[i, 0]) / g
    if q >= 1.0:
        return -1.0
    if q < -1.0:
        return math.inf
    return math.acos(q)


@leaf_kernel
def _held_until(tr, i, t, edge):  # type: ignore[no-untyped-def]
    """A time up to which f > 0 is certified from t on by row i's first term alone, else t.

    ``edge``: the row's :func:`_held_edge`, taken once by a search that asks often.
    """
    if edge < 0.0:
        return t
    if edge == math.inf:
        return math.inf
    w = tr[i, _TW]
    r = (w * t + tr[i, _TP] + math.pi) % _TWO_PI - math.pi
    if -edge < r < edge:
        return t + (edge - r) / w * (1.0 - 1e-9)
    return t


@leaf_kernel
def _product_arcs(tr, i):  # type: ignore[no-untyped-def]
    """Where a product-form row may be ≤ 0: (shift, a1, b1, a2, b2), arcs [a1, b1], [a2, b2] of y = ω_r t + shift.

    A row in product form (N, or a no-slip margin: ``_T_N_FORM``) is f = c − G·S with G = g − κ sin α in
    [g − |κ|, g + |κ|] at every cam phase and S = u sin θ + v cos θ = R sin y, y = θ + atan2(v, u), R = √(u² + v²).
    So f ≥ c − (g + |κ|) S where S ≥ 0 and f ≥ c − (g − |κ|) S where S < 0: f > 0 while
    sin y < c/((g + |κ|) R) and, when g < |κ| (the cam can lift the powder off: G < 0 at some phase),
    sin y > −c/((|κ| − g) R). The complement, one arc of y (mod 2π) for each bound that is below 1, is
    returned; an absent arc is (7, 7) (above 2π). For N (u = 1, v = 0) the first arc starts at
    sin θ = r0 ω_r²/(g + r_d ω_v²), where the studies' level-(b) sample starts (:mod:`millctl.studies.phase_integral`);
    the slow term's certificate (:func:`_held_edge`) is the weaker bound (c − |κ|)/g there. (7, 7, 7, 7, 7) with
    shift nan: not a product row, or c ≤ 0, nothing certified.
    """
    form = tr[i, _T_N_FORM]
    c, w = tr[i, 0], tr[i, _TW]
    if (form != _FORM_N and form != _FORM_MARGIN) or c <= 0.0 or w <= 0.0:
        return math.nan, 7.0, 7.0, 7.0, 7.0
    if form == _FORM_N:
        g, u, v = tr[i, _TA], 1.0, 0.0
    else:
        g, u, v = tr[i, _T_G], tr[i, _T_U], tr[i, _T_V]
    kappa = abs(tr[i, _T_KAPPA])
    r = math.sqrt(u * u + v * v)
    q_hi = c / ((g + kappa) * r)
    q_lo = c / ((kappa - g) * r) if kappa > g else math.inf
    a1 = b1 = a2 = b2 = 7.0
    if q_hi < 1.0:
        a1 = math.asin(q_hi)
        b1 = math.pi - a1
    if q_lo < 1.0:
        a2 = math.pi + math.asin(q_lo)
        b2 = _TWO_PI - math.asin(q_lo)
    return tr[i, _T_TH0] + math.atan2(v, u), a1, b1, a2, b2


@leaf_kernel
def _product_until(tr, i, t, arcs):  # type: ignore[no-untyped-def]
    """A time up to which f > 0 is certified from t on by the product bound (:func:`_product_arcs` ``arcs``), else t."""
    shift, a1, b1, a2, b2 = arcs
    if shift != shift:  # nan: no certificate
        return t
    if a1 > _TWO_PI and a2 > _TWO_PI:
        return math.inf
    w = tr[i, _TW]
    y = (w * t + shift) % _TWO_PI
    if a1 <= y <= b1 or a2 <= y <= b2:
        return t
    ahead = min((a1 - y) % _TWO_PI if a1 <= _TWO_PI else math.inf, (a2 - y) % _TWO_PI if a2 <= _TWO_PI else math.inf)
    return t + ahead / w * (1.0 - 1e-9)


@leaf_kernel
def _falling_zero_windowed(p, st, tr, i, sign, t0, t1):  # type: ignore[no-untyped-def]
    """_falling_zero over [t0, t1], one window at a time from where N can first vanish, stopping at the first root."""
    w = _window_s(p)
    edge = _held_edge(tr, i) if sign > 0.0 else -1.0
    arcs = _product_arcs(tr, i) if sign > 0.0 else (math.nan, 7.0, 7.0, 7.0, 7.0)
    a = t0
    while a < t1:
        if sign > 0.0:
            a = max(a, _held_until(tr, i, a, edge), _product_until(tr, i, a, arcs))
            if a >= t1:
                return math.inf
        b = min(a + w, t1)
        if _trig(tr, i, a, 0, sign) <= 0.0:
            return a
        root = _falling_zero(p, st, tr, i, sign, a, b)
        if root < math.inf:
            return root
        a = b
    return math.inf


@leaf_kernel
def _nudge(tr, i, t, horizon, sign):  # type: ignore[no-untyped-def]
    """The first time from t on where sign·N > 0, stepping geometrically off a root (inf: none)."""
    step = max(abs(t), 1.0) * 1e-13
    while _trig(tr, i, t, 0, sign) <= 0.0:
        if t >= horizon:
            return math.inf
        t, step = t + step, 2.0 * step
    return t


@leaf_kernel
def _rearm(p, st, tr, i, t_start, horizon):  # type: ignore[no-untyped-def]
    """Skip the current dip of N: the first time after t_start at which N > 0 again after having been < 0."""
    t = t_start
    if _trig(tr, i, t, 0, 1.0) >= 0.0:
        down = _falling_zero_windowed(p, st, tr, i, 1.0, t, horizon) if _trig(tr, i, t, 0, 1.0) > 0.0 else t
        if down == math.inf:
            return math.inf
        t = _nudge(tr, i, down, horizon, -1.0)
        if t == math.inf:
            return math.inf
    up = _falling_zero_windowed(p, st, tr, i, -1.0, t, horizon)
    return math.inf if up == math.inf else _nudge(tr, i, up, horizon, 1.0)


@leaf_kernel
def _never_detaches(tr, i):  # type: ignore[no-untyped-def]
    """Certified: N ≥ c − Σ|a_k| > 0 at every time."""
    return tr[i, 0] - _trig_bound(tr, i, 0) > 0.0


@njit(cache=True, error_model="numpy")
def _detachment_times(p, horizon):  # type: ignore[no-untyped-def]
    n = int(p[_N])
    tr = _trig_rows(p, n)
    st = np.zeros((n, _STATE_COLUMNS))
    out = np.full(n, math.inf)
    for i in range(n):
        if _trig(tr, i, 0.0, 0, 1.0) <= 0.0:
            out[i] = 0.0
        elif not _never_detaches(tr, i):
            out[i] = _falling_zero_windowed(p, st, tr, i, 1.0, 0.0, horizon)
    return out


def detachment_times(row: FloatArray, horizon_s: float) -> FloatArray:
    """Every rod's first detachment in [0, horizon] (s; inf: pinned), compiled.

    The shared search the benchmark times on its own (zero-length departures are not resolved here).
    """
    result: FloatArray = _detachment_times(np.ascontiguousarray(row, dtype=np.float64), float(horizon_s))
    return result


__all__ = ["detachment_times"]

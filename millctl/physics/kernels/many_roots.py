"""Level (c) compiled, the contact roots: the separation of a flying rod in its own clock τ and Brent's method on it.

The mover's separation from the wall (eq. 10's flight against r0; right after a departure the wall gap with
the departure's triple root divided out, :func:`millctl.physics.flight.departure_wall_gap`) or from another
rod (eq. 13 with 2 r_r), its derivative, and the roots :mod:`.many_event`'s contact search resolves
(the reference: :func:`millctl.physics.events._resolve`).
"""

from __future__ import annotations

import math

from numba import njit

from millctl.physics.kernels.layout import (
    _G,
    _MAXITER,
    _R0,
    _RD,
    _RR,
    _RTOL,
    _S_CA,
    _S_DW,
    _S_ND,
    _S_SA,
    _S_T0,
    _S_X,
    _S_Y,
    _WR,
    _WV,
    WALL,
)
from millctl.physics.kernels.motion import _c2_plus_half_over_x, _flying_rel, _rel, _s3
from millctl.physics.kernels.roots import _xtol

_SEP, _DSEP = 0, 1
"""Which function :func:`_g` evaluates: the separation, or its derivative in τ."""


@njit(cache=True)
def _gap_tau(p, st, i, tau):  # type: ignore[no-untyped-def]
    """flight.departure_wall_gap in the flight's own clock τ: the wall gap with the departure root divided out."""
    r0, w_r, w_v, r_d, g = p[_R0], p[_WR] + st[i, _S_DW], p[_WV], p[_RD], p[_G]  # w_r: the departure rate
    s_d, c_d = st[i, _S_Y] / r0, st[i, _S_X] / r0
    x = w_v * tau
    sa, ca = st[i, _S_SA], st[i, _S_CA]
    d_eta = -r_d * w_v**3 * (sa * _c2_plus_half_over_x(x) + ca * _s3(x))
    eta = -0.5 * g + 0.5 * r_d * w_v * w_v * sa + d_eta * tau
    reduced = 2.0 * r0 * (d_eta * s_d + eta * w_r * c_d) + eta * eta * tau
    n_d = st[i, _S_ND]
    return -reduced if n_d == 0.0 else -(n_d + tau * reduced)


@njit(cache=True)
def _g(code, p, st, i, j, tau, reduced):  # type: ignore[no-untyped-def]
    """The separation (``code`` _SEP; the reduced wall gap when ``reduced``) or its derivative of mover i, at τ."""
    if reduced and code == _SEP:
        return _gap_tau(p, st, i, tau)
    x, y, vx, vy = _flying_rel(p, st, i, tau, math.cos(p[_WV] * tau), math.sin(p[_WV] * tau))
    if j == WALL:
        return p[_R0] * p[_R0] - (x * x + y * y) if code == _SEP else -2.0 * (x * vx + y * vy)
    xb, yb, vxb, vyb = _rel(p, st, j, st[i, _S_T0] + tau)
    dx, dy = x - xb, y - yb
    if code == _SEP:
        return dx * dx + dy * dy - 4.0 * p[_RR] * p[_RR]
    return 2.0 * (dx * (vx - vxb) + dy * (vy - vyb))


@njit(cache=True)
def _brent(code, p, st, i, j, reduced, xa, xb, xtol):  # type: ignore[no-untyped-def]
    """Brent's method (scipy's brentq, as :func:`.roots._brentq`) on :func:`_g`; no sign change: the left end.

    A second copy of the loop, not a call: :func:`.roots._brentq` picks its function by a code of the batch
    kernel's (:func:`.roots._f`, in absolute time), and a compiled, cached kernel cannot take the function as
    an argument without losing its inlining; this one works in the mover's clock τ with the reduced wall gap.
    """
    xpre, xcur = xa, xb
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    fpre, fcur = _g(code, p, st, i, j, xpre, reduced), _g(code, p, st, i, j, xcur, reduced)
    if fpre == 0.0:
        return xpre
    if fcur == 0.0:
        return xcur
    if (fpre < 0.0) == (fcur < 0.0):
        return xpre
    for _ in range(_MAXITER):
        if fpre != 0.0 and fcur != 0.0 and (fpre < 0.0) != (fcur < 0.0):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = 0.5 * (xtol + _RTOL * abs(xcur))
        sbis = 0.5 * (xblk - xcur)
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre, dblk = (fpre - fcur) / (xpre - xcur), (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry
            else:
                spre, scur = sbis, sbis
        else:
            spre, scur = sbis, sbis
        xpre, fpre = xcur, fcur
        xcur += scur if abs(scur) > delta else (delta if sbis > 0.0 else -delta)
        fcur = _g(code, p, st, i, j, xcur, reduced)
    return xcur


@njit(cache=True)
def _root(p, st, i, j, reduced, a, b, tol):  # type: ignore[no-untyped-def]
    """events._root: b when the function vanishes there, else Brent to max(tol, 4 ulp)."""
    if _g(_SEP, p, st, i, j, b, reduced) == 0.0:
        return b
    return _brent(_SEP, p, st, i, j, reduced, a, b, _xtol(a, b, tol))


@njit(cache=True)
def _resolve(p, st, i, j, reduced, a, b, tol):  # type: ignore[no-untyped-def]
    """events._resolve: the contact τ in [a, b] of one candidate interval, or inf (a minimum that stays apart)."""
    if _g(_SEP, p, st, i, j, b, reduced) <= 0.0:
        return _root(p, st, i, j, reduced, a, b, tol)
    if _g(_DSEP, p, st, i, j, a, reduced) < 0.0 < _g(_DSEP, p, st, i, j, b, reduced):
        t_m = _brent(_DSEP, p, st, i, j, reduced, a, b, _xtol(a, b, 0.0))
        if _g(_SEP, p, st, i, j, t_m, reduced) <= 0.0:
            return _root(p, st, i, j, reduced, a, t_m, tol)
    return math.inf

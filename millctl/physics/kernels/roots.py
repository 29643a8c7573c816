"""Brent's bracketed root finder, a line-by-line port of scipy's ``brentq`` (Zeros/brentq.c), on the kernels' functions.

The same tolerances as the reference engine, so that both stop on the same test. The function is named
by a code (``_F_*`` in :mod:`.layout`): N, N′, −N, −N′ (detachment) or the separation and its
derivative (contacts), evaluated by :func:`_f`.
"""

from __future__ import annotations

from millctl.physics.kernels.layout import (
    _F_DN,
    _F_N,
    _F_NEG_DN,
    _F_NEG_N,
    _F_SIGN_SEP,
    _MAXITER,
    _RTOL,
    _S_FLY,
    WALL,
    leaf_kernel,
)
from millctl.physics.kernels.motion import _departure_gap, _pair
from millctl.physics.kernels.trig import _trig


@leaf_kernel
def _f(code, p, st, tr, i, j, t):  # type: ignore[no-untyped-def]
    """The function the root finder works on (code: N, N', −N, −N', sign separation, d separation)."""
    if code == _F_N:
        return _trig(tr, i, t, 0, 1.0)
    if code == _F_DN:
        return _trig(tr, i, t, 1, 1.0)
    if code == _F_NEG_N:
        return _trig(tr, i, t, 0, -1.0)
    if code == _F_NEG_DN:
        return _trig(tr, i, t, 1, -1.0)
    if code == _F_SIGN_SEP and j == WALL and st[i, _S_FLY] != 0.0:
        return _departure_gap(p, st, i, t)
    s, ds, _ = _pair(p, st, i, j, t)
    return s if code == _F_SIGN_SEP else ds


@leaf_kernel
def _brentq(code, p, st, tr, i, j, xa, xb, xtol, rtol):  # type: ignore[no-untyped-def]
    """Brent's method, scipy's brentq (Zeros/brentq.c), on _f; a bracket without a sign change returns its left end."""
    fa, fb = _f(code, p, st, tr, i, j, xa), _f(code, p, st, tr, i, j, xb)
    return _brentq_from(code, p, st, tr, i, j, xa, xb, fa, fb, xtol, rtol)


@leaf_kernel
def _brentq_from(code, p, st, tr, i, j, xa, xb, fa, fb, xtol, rtol):  # type: ignore[no-untyped-def]
    """:func:`_brentq` given fa, fb = _f at xa, xb, as the caller has them (the same root, two evaluations fewer)."""
    xpre, xcur = xa, xb
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    fpre, fcur = fa, fb
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
        delta = 0.5 * (xtol + rtol * abs(xcur))
        sbis = 0.5 * (xblk - xcur)
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry
            else:
                spre, scur = sbis, sbis
        else:
            spre, scur = sbis, sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0.0 else -delta
        fcur = _f(code, p, st, tr, i, j, xcur)
    return xcur


@leaf_kernel
def _xtol(a, b, tol):  # type: ignore[no-untyped-def]
    return max(tol, _RTOL * max(abs(a), abs(b)), 1e-300)

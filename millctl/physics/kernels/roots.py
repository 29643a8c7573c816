"""Bracketed root finders on the kernels' functions: Brent's method, and Newton's where the slope comes free.

* :func:`_brentq_from`: a line-by-line port of scipy's ``brentq`` (Zeros/brentq.c), with the reference
  engine's tolerances, so that both stop on the same test (N's critical points, the wall gap);
* :func:`_newton_from`: Newton's method kept inside the bracket, on the same stopping test, where the slope
  comes free: N's falling zeros (the same sines and cosines give N′, :func:`.trig._trig012`) and a rod pair's
  separation (the same two positions, :func:`.motion._pair`), started from the cubic through the bracket's
  end values and slopes (:func:`_hermite_start`).

The function is named by a code (``_F_*`` in :mod:`.layout`): N, N′, −N, −N′ (detachment) or the separation
and its derivative (contacts), evaluated by :func:`_f`.
"""

from __future__ import annotations

import math

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
from millctl.physics.kernels.trig import _trig, _trig012


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
def _f_slope(code, p, st, tr, i, j, t):  # type: ignore[no-untyped-def]
    """The function and its slope at t where the slope comes free: ±N (a trig row), a rod pair's separation."""
    if code == _F_N:
        f, df, _ = _trig012(tr, i, t, 1.0)
        return f, df
    if code == _F_NEG_N:
        f, df, _ = _trig012(tr, i, t, -1.0)
        return f, df
    s, ds, _ = _pair(p, st, i, j, t)
    return s, ds


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


@leaf_kernel
def _hermite_start(xa, xb, fa, dfa, fb, dfb):  # type: ignore[no-untyped-def]
    """The root in (xa, xb) of the cubic that matches f and f′ at both ends (nan: none found there).

    Newton's method on the cubic from the secant's root, a few steps of arithmetic; the cubic is within
    O(width⁴ f⁗) of f, so the root finder starts where one Newton step on f reaches rounding.
    """
    width = xb - xa
    ma, mb = dfa * width, dfb * width  # slopes in the step's own variable u ∈ [0, 1]
    u = fa / (fa - fb)
    for _ in range(4):
        u2 = u * u
        u3 = u2 * u
        value = (2.0 * u3 - 3.0 * u2 + 1.0) * fa + (u3 - 2.0 * u2 + u) * ma
        value += (3.0 * u2 - 2.0 * u3) * fb + (u3 - u2) * mb
        slope = (6.0 * u2 - 6.0 * u) * (fa - fb) + (3.0 * u2 - 4.0 * u + 1.0) * ma + (3.0 * u2 - 2.0 * u) * mb
        if slope == 0.0:
            return math.nan
        u -= value / slope
        if not (0.0 < u < 1.0):
            return math.nan
    return xa + u * width


@leaf_kernel
def _newton_from(code, p, st, tr, i, j, xa, xb, fa, dfa, fb, dfb, xtol, rtol):  # type: ignore[no-untyped-def]
    """Newton's method inside the bracket [xa, xb] on a function whose slope comes free, given both at both ends.

    ``code``: ±N of trig row i (its slope from the same two sines and cosines, :func:`.trig._trig012`), or
    the separation of rods i and j (from the same two positions, :func:`.motion._pair`); :func:`_f_slope`.
    The contract and stopping test of :func:`_brentq_from` (a root within ½(xtol + rtol·|x|)), about half of
    Brent's evaluations. A slope of nan: unknown. It starts at the root of the cubic
    through both ends' values and slopes (:func:`_hermite_start`), else the tangent at xb, else the secant; a
    step that would leave the bracket, or shrink it by less than half of the step before, bisects instead
    ("rtsafe", Numerical Recipes §9.4).
    """
    if fa == 0.0:
        return xa
    if fb == 0.0:
        return xb
    if (fa < 0.0) == (fb < 0.0):
        return xa
    lo, hi = (xa, xb) if fa < 0.0 else (xb, xa)  # f(lo) < 0 < f(hi)
    inside_lo, inside_hi = min(xa, xb), max(xa, xb)
    x = _hermite_start(xa, xb, fa, dfa, fb, dfb) if dfa == dfa and dfb == dfb else math.nan
    if not (inside_lo < x < inside_hi):  # nan included
        x = xb - fb / dfb if dfb != 0.0 else math.nan
    if not (inside_lo < x < inside_hi):
        x = xa - fa * (xb - xa) / (fb - fa)
        if not (inside_lo < x < inside_hi):
            x = 0.5 * (xa + xb)
    step_before = abs(xb - xa)
    step = step_before
    f, df = _f_slope(code, p, st, tr, i, j, x)
    for _ in range(_MAXITER):
        if f == 0.0:
            return x
        if f < 0.0:
            lo = x
        else:
            hi = x
        delta = 0.5 * (xtol + rtol * abs(x))
        leaves = ((x - hi) * df - f) * ((x - lo) * df - f) > 0.0
        if leaves or abs(2.0 * f) > abs(step_before * df):
            step_before, step = step, 0.5 * (hi - lo)
            x = lo + step
        else:
            step_before, step = step, f / df
            x -= step
        if abs(step) < delta or abs(hi - lo) < delta:
            return x
        f, df = _f_slope(code, p, st, tr, i, j, x)
    return x

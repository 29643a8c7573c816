"""Brent's bracketed root finder in plain Python: scipy's ``brentq`` (Zeros/brentq.c) without importing scipy.

Why a copy: :mod:`.detachment` runs in the node's telemetry and the service's recipe
planner, and ``scipy.optimize`` was the largest single import of both processes
(issue 36, part 5: every process start in the VM tier pays it ~9 times over).
A lazy import would only move that cost into the first telemetry revolution of a
running node, so the algorithm is here instead.

The iteration is the one of scipy's C loop (Brent 1973, ch. 4; the same as the compiled
:func:`millctl.physics.kernels.roots._brentq`): the bracket [xa, xb] is kept, each step
is inverse quadratic (or linear) interpolation when it is short and safe, a bisection
otherwise, and the loop stops when half the bracket is below
``delta = (xtol + rtol·|x|)/2`` — so on the same function it returns the same float as
``scipy.optimize.brentq`` (tests/unit/physics/test_roots.py compares them).
"""

from __future__ import annotations

import math
from collections.abc import Callable

EPS = 2.220446049250313e-16
"""Machine epsilon of a float64 (numpy's ``finfo(float).eps``)."""
RTOL_MIN = 4.0 * EPS
"""The smallest relative tolerance accepted, scipy's ``_rtol``: tighter cannot be met in float64."""
XTOL_DEFAULT = 2e-12
"""scipy's default absolute tolerance (in the units of x)."""
MAXITER_DEFAULT = 100
"""scipy's default iteration cap."""


class RootNotConverged(RuntimeError):
    """Brent's method ran out of iterations before the bracket shrank to the tolerance."""


def _value(f: Callable[[float], float], x: float) -> float:
    """f(x) as a float; a NaN is refused (scipy's ``_wrap_nan_raise``), it has no sign to bracket with."""
    value = float(f(x))
    if math.isnan(value):
        raise ValueError(f"brentq: f({x!r}) is NaN; a root needs a function with a sign on the bracket")
    return value


def _interpolation_step(xpre: float, fpre: float, xcur: float, fcur: float, xblk: float, fblk: float) -> float:
    """The secant step (xpre = xblk) or the inverse quadratic one through the three points, from xcur.

    NaN where C's IEEE arithmetic would divide by zero (flat f, coincident points): the C loop
    gets ±inf or NaN there, which fails its short-step test, and so bisects; Python raises
    instead, so the NaN gives the caller the same bisection.
    """
    try:
        if xpre == xblk:
            return -fcur * (xcur - xpre) / (fcur - fpre)
        dpre = (fpre - fcur) / (xpre - xcur)
        dblk = (fblk - fcur) / (xblk - xcur)
        return -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
    except ZeroDivisionError:
        return math.nan


def brentq(
    f: Callable[[float], float],
    xa: float,
    xb: float,
    xtol: float = XTOL_DEFAULT,
    rtol: float = RTOL_MIN,
    maxiter: int = MAXITER_DEFAULT,
) -> float:
    """A root of f in [xa, xb] where f(xa) and f(xb) differ in sign, to ``|x − x*| ≤ xtol + rtol·|x*|``.

    Same arguments, same result and same refusals as ``scipy.optimize.brentq``:
    ValueError when f has one sign at both ends, when f is NaN, when ``xtol ≤ 0``
    or ``rtol < 4·eps``; :class:`RootNotConverged` after ``maxiter`` iterations.
    """
    if not xtol > 0.0:
        raise ValueError(f"brentq: xtol = {xtol!r} must be > 0 (a root at x = 0 has no relative scale)")
    if not rtol >= RTOL_MIN:
        raise ValueError(f"brentq: rtol = {rtol!r} must be >= 4·eps = {RTOL_MIN!r} (float64 cannot resolve less)")
    xpre, xcur = float(xa), float(xb)
    xblk, fblk, spre, scur = 0.0, 0.0, 0.0, 0.0
    fpre, fcur = _value(f, xpre), _value(f, xcur)
    if fpre == 0.0:
        return xpre
    if fcur == 0.0:
        return xcur
    if math.copysign(1.0, fpre) == math.copysign(1.0, fcur):
        raise ValueError(f"brentq: f({xpre!r}) = {fpre!r} and f({xcur!r}) = {fcur!r} have one sign: no root bracketed")
    for _ in range(maxiter):
        if fpre != 0.0 and fcur != 0.0 and math.copysign(1.0, fpre) != math.copysign(1.0, fcur):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):  # keep the best estimate in xcur, the other end of the bracket in xblk
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = 0.5 * (xtol + rtol * abs(xcur))
        sbis = 0.5 * (xblk - xcur)
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            stry = _interpolation_step(xpre, fpre, xcur, fcur, xblk, fblk)
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry  # a short step: accept the interpolation
            else:
                spre, scur = sbis, sbis
        else:
            spre, scur = sbis, sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0.0 else -delta
        fcur = _value(f, xcur)
    raise RootNotConverged(f"brentq: no convergence after maxiter = {maxiter} iterations, last x = {xcur!r}")


__all__ = ["MAXITER_DEFAULT", "RTOL_MIN", "XTOL_DEFAULT", "RootNotConverged", "brentq"]

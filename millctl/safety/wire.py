"""What the node receives: every wire-rounded sample of a planned move, checked against the envelope.

The controller samples its ramp at the setpoint period and sends each pair
rounded onto the wire's grid (0.1 rpm, ``config/millbus.dbc``; a CiA 402
drive's own unit, :mod:`millctl.safety.grid`); the node checks the rounded
pair. Checking the straight line itself is not enough: a line that stays
inside can round to a point just outside where it runs close to the limit
(docs/safety.md#whole-ramp-check). Since the sampling instant is arbitrary,
the planner checks *every* rounded pair the line can produce.

Along a segment from A to B each axis is a monotone function of the fraction
f ∈ [0, 1], so its rounded value changes only where it crosses a half-grid
boundary (k + ½)·q. Between consecutive crossings the rounded pair is
constant; at a crossing either neighbour's value of each axis may be sent,
so the four combinations of the two neighbours are checked too. The result
is exact for any sampling, not a sample of samples.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from millctl.safety.envelope import Envelope, Verdict
from millctl.safety.grid import AxisGrid, ScaledGrid

Resolution = float | tuple[AxisGrid, AxisGrid]
"""One grid step for both axes (rpm, the millbus wire's kind), or each axis's own grid (rotary, vibration)."""


def axis_grids(resolution: Resolution) -> tuple[AxisGrid, AxisGrid]:
    """Both axes' grids from either form of :data:`Resolution`."""
    if isinstance(resolution, tuple):
        return resolution
    grid = ScaledGrid(resolution)
    return grid, grid


def _crossings(start: float, end: float, resolution: float) -> NDArray[np.float64]:
    """The fractions f ∈ (0, 1) at which start + f·(end − start) crosses a half-grid boundary."""
    if start == end:
        return np.empty(0)
    low, high = min(start, end), max(start, end)
    first = math.ceil(low / resolution - 0.5)
    last = math.floor(high / resolution - 0.5)
    if last < first:
        return np.empty(0)
    boundaries = (np.arange(first, last + 1, dtype=float) + 0.5) * resolution
    fractions = (boundaries - start) / (end - start)
    return np.asarray(fractions[(fractions > 0.0) & (fractions < 1.0)], dtype=float)


def rounded_samples(
    start: tuple[float, float], end: tuple[float, float], resolution: Resolution
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Every rounded pair a straight segment can put on the wire: fractions f, ω_r (rpm) and ω_v (rpm).

    ``start`` and ``end`` are (ω_r, ω_v) in rpm; the fraction of each pair is
    where along the segment it is sent (a crossing's for the combinations).
    """
    (r0, v0), (r1, v1) = start, end
    grid_r, grid_v = axis_grids(resolution)
    fractions = np.unique(np.concatenate(
        ([0.0, 1.0], _crossings(r0, r1, grid_r.step_rpm), _crossings(v0, v1, grid_v.step_rpm))
    ))
    mids = (fractions[:-1] + fractions[1:]) / 2.0
    at = np.concatenate(([0.0], mids, [1.0]))
    w_r = grid_r.snap(r0 + at * (r1 - r0))
    w_v = grid_v.snap(v0 + at * (v1 - v0))
    # at each crossing, the rounded value of one axis from before with the other's from after
    crossing = fractions[1:-1]
    n = len(crossing)
    mixed_r = np.concatenate((w_r[1 : n + 1], w_r[2 : n + 2]))
    mixed_v = np.concatenate((w_v[2 : n + 2], w_v[1 : n + 1]))
    return (
        np.concatenate((at, crossing, crossing)),
        np.concatenate((w_r, mixed_r)),
        np.concatenate((w_v, mixed_v)),
    )


def first_wire_violation(
    segments: list[tuple[float, float, tuple[float, float], tuple[float, float]]],
    envelope: Envelope,
    resolution: Resolution,
) -> tuple[float, Verdict] | None:
    """The earliest instant (s) whose rounded setpoint pair is outside, with the verdict; None when all inside.

    ``segments`` are (t0 s, t1 s, (ω_r, ω_v) start, (ω_r, ω_v) end) in rpm.
    """
    for t0_s, t1_s, start, end in segments:
        fractions, w_r, w_v = rounded_samples(start, end, resolution)
        inside = envelope.contains(w_r, w_v)
        if bool(np.all(inside)):
            continue
        outside = np.flatnonzero(~inside)
        i = outside[np.argmin(fractions[outside])]
        verdict = envelope.check(float(w_r[i]), float(w_v[i]))
        return t0_s + float(fractions[i]) * (t1_s - t0_s), verdict
    return None


__all__ = ["Resolution", "axis_grids", "first_wire_violation", "rounded_samples"]

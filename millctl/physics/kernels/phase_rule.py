"""Level (b)'s adaptive cam-phase integral, compiled: every point's samples, their trapezoid weights and error.

The rule of :mod:`millctl.studies.phase_integral` (its docstring states it), point by point in one call:
K0 = 8 even lift phases, every interval bisected once, then the intervals that score above their share of
the error budget, or whose ends land differently, bisected until the budget holds, the point has taken
:data:`MAX_CAM_PHASES` samples or an interval is :data:`FINEST_PHASE_RAD` wide. A sample is rod 0's one-rod
event and no-slip check at that phase (:func:`.telemetry._samples_into`); the rule reads six *controls* of it
(:func:`_controls_into`). Each point is refined from its own samples only, in rounds (every interval a round
chooses is bisected before the next round scores), so a point's samples do not depend on its batch.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from millctl.physics.kernels.layout import _N, _TWO_PI, _WR, TELEMETRY, FloatArray
from millctl.physics.kernels.telemetry import _samples_into, _telemetry_work

FIRST_PHASES = 8
"""K0: the even phases an integral starts from (then every interval is bisected once)."""
MAX_CAM_PHASES = 256
"""A point stops refining once it has taken this many samples (the round that passes it finishes)."""
FINEST_PHASE_RAD = 2.0 * math.pi / 4096
"""The narrowest interval the integral bisects (rad of lift phase)."""
_CAPACITY = 2 * MAX_CAM_PHASES
"""Samples (and intervals) a point can hold: a round adds at most one a sample it has."""
_C_FOUND, _C_DEPART, _C_THETA_D, _C_ENERGY, _C_FLIGHT, _C_WALL, _C_CONTACT, _C_SLIP = (
    TELEMETRY.index(name)
    for name in (
        "found", "depart_time_s", "theta_d_rad", "energy_j", "flight_time_s", "on_wall", "theta_contact_rad",
        "slip_theta_rad",
    )
)  # fmt: skip
"""The telemetry columns the rule reads (:data:`.layout.TELEMETRY`)."""
_PHASE, _WEIGHT, _OWNER = len(TELEMETRY), len(TELEMETRY) + 1, len(TELEMETRY) + 2
"""The columns :func:`_integrate` adds to a sample's telemetry row: its lift phase, trapezoid weight and point."""


@njit(cache=True, error_model="numpy")
def _controls_into(w_r, min_w_r, threshold_j, t, out):  # type: ignore[no-untyped-def]
    """What the rule reads of a telemetry row ``t``, into ``out`` (6 words).

    The four integrands it controls — counted (a landing at or above the impact threshold), counted · p
    (collisions per revolution), counted · energy, slipping — then the departure time (s; nan without a
    landing) and the wall landing (0/1; nan without one). The formulas of ``phase_integral._per_sample``.
    """
    moving = w_r >= min_w_r
    landed = t[_C_FOUND] == 1.0 and moving
    counted = landed and t[_C_ENERGY] >= threshold_j
    per_rev = 1.0
    if t[_C_WALL] == 1.0:
        travel = (t[_C_THETA_D] - t[_C_CONTACT]) % _TWO_PI
        cycle_s = t[_C_FLIGHT] + travel / w_r
        per_rev = _TWO_PI / (w_r * cycle_s) if cycle_s > 0.0 else 1.0
    out[0] = 1.0 if counted else 0.0
    out[1] = per_rev if counted else 0.0
    out[2] = t[_C_ENERGY] if counted else 0.0
    out[3] = 1.0 if (math.isfinite(t[_C_SLIP]) and moving) else 0.0
    out[4] = t[_C_DEPART] if landed else math.nan
    out[5] = t[_C_WALL] if landed else math.nan


@njit(cache=True, error_model="numpy")
def _kind_changes(a, b, lift_period_s):  # type: ignore[no-untyped-def]
    """An interval whose ends land differently: counted or not, on the wall or a rod, or a lift cycle apart."""
    cycle = abs(b[4] - a[4]) > 0.5 * lift_period_s  # nan (no landing at an end): False
    partner = a[5] != b[5] and a[0] == 1.0 and b[0] == 1.0
    return a[0] != b[0] or cycle or partner


@njit(cache=True, error_model="numpy")
def _ratio(delta, scale):  # type: ignore[no-untyped-def]
    """|Δ| / scale, 0 where Δ is 0 and ∞ where only the scale is."""
    return 0.0 if delta == 0.0 else delta / scale


@njit(cache=True, error_model="numpy")
def _refine_point(i, rows, start, pinned, w_r, lift_period_s, min_w_r, threshold_j, rtol, flight_cap, mu, buf):  # type: ignore[no-untyped-def]
    """Point i's integral into ``buf``'s arrays; returns (samples, intervals, samples taken).

    ``buf``: (telemetry rows, controls, sample phases, interval lo, hi, a, b, score, chosen, scene index,
    work) — :func:`_point_buffers`. Interval k runs from ``lo[k]`` to ``hi[k]`` (rad), its end samples are rows
    ``a[k]``, ``b[k]``; a bisection keeps the left half in place and appends the right one.
    """
    table, ctrl, phase, lo, hi, ra, rb, score, chosen, scene, work = buf
    k0 = FIRST_PHASES
    for k in range(k0):
        phase[k], lo[k], hi[k] = _TWO_PI * k / k0, _TWO_PI * k / k0, _TWO_PI * (k + 1) / k0
        ra[k], rb[k], score[k] = k, (k + 1) % k0, math.inf  # not yet bisected
        scene[k] = i
    _samples_into(rows, start, pinned, scene[:k0], phase[:k0], flight_cap, mu, table[:k0], work)
    for k in range(k0):
        _controls_into(w_r, min_w_r, threshold_j, table[k], ctrl[k])
    samples, intervals, used = k0, k0, k0
    while True:
        means0 = means1 = means2 = total = 0.0
        for k in range(intervals):
            half = 0.5 * (hi[k] - lo[k]) / _TWO_PI
            means0 += half * (ctrl[ra[k], 0] + ctrl[rb[k], 0])
            means1 += half * (ctrl[ra[k], 1] + ctrl[rb[k], 1])
            means2 += half * (ctrl[ra[k], 2] + ctrl[rb[k], 2])
            total += score[k]
        share = 1.0 / max(intervals, 1)
        picks = 0
        for k in range(intervals):
            width = hi[k] - lo[k]
            over = total > 1.0 and score[k] > share
            unplaced = 0.5 * width / _TWO_PI > 0.25 * rtol and _kind_changes(ctrl[ra[k]], ctrl[rb[k]], lift_period_s)
            if (over or unplaced) and used < MAX_CAM_PHASES and width > FINEST_PHASE_RAD:
                chosen[picks] = k
                picks += 1
        if picks == 0:
            return samples, intervals, used
        for c in range(picks):
            k = chosen[c]
            phase[samples + c], scene[samples + c] = 0.5 * (lo[k] + hi[k]), i
        new = samples
        _samples_into(
            rows, start, pinned, scene[new : new + picks], phase[new : new + picks], flight_cap, mu,
            table[new : new + picks], work,
        )  # fmt: skip
        for c in range(picks):
            k, m = chosen[c], new + c
            _controls_into(w_r, min_w_r, threshold_j, table[m], ctrl[m])
            span = (hi[k] - lo[k]) / _TWO_PI
            d0 = abs(0.25 * span * (2.0 * ctrl[m, 0] - ctrl[ra[k], 0] - ctrl[rb[k], 0]))
            d1 = abs(0.25 * span * (2.0 * ctrl[m, 1] - ctrl[ra[k], 1] - ctrl[rb[k], 1]))
            d2 = abs(0.25 * span * (2.0 * ctrl[m, 2] - ctrl[ra[k], 2] - ctrl[rb[k], 2]))
            d3 = abs(0.25 * span * (2.0 * ctrl[m, 3] - ctrl[ra[k], 3] - ctrl[rb[k], 3]))
            power = _ratio(d0, means0) + _ratio(d1, means1) + _ratio(d2, means2)  # the milling power ∝ B·C/A
            eps = max(max(d0, d3), power) / rtol
            right = intervals + c
            lo[right], hi[right], ra[right], rb[right], score[right] = phase[m], hi[k], m, rb[k], 0.5 * eps
            hi[k], rb[k], score[k] = phase[m], m, 0.5 * eps
        samples += picks
        intervals += picks
        used += picks


@njit(cache=True, error_model="numpy")
def _integrate(rows, start, pinned, w_r, lift_period_s, min_w_r, threshold_j, rtol, flight_cap, mu):  # type: ignore[no-untyped-def]
    """Every point's samples, one row each: its telemetry, then :data:`_PHASE`, :data:`_WEIGHT`, :data:`_OWNER`."""
    size = rows.shape[0]
    out = np.empty((max(size * 2 * FIRST_PHASES, 1), _OWNER + 1))
    used, error = np.zeros(size), np.zeros(size)
    buf = (
        np.empty((_CAPACITY, len(TELEMETRY))), np.empty((_CAPACITY, 6)), np.empty(_CAPACITY),
        np.empty(_CAPACITY), np.empty(_CAPACITY), np.empty(_CAPACITY, dtype=np.int64),
        np.empty(_CAPACITY, dtype=np.int64), np.empty(_CAPACITY), np.empty(_CAPACITY, dtype=np.int64),
        np.empty(_CAPACITY, dtype=np.int64), _telemetry_work(int(rows[:, _N].max()) if size > 0 else 1),
    )  # fmt: skip
    node_weight = np.empty(_CAPACITY)
    filled = 0
    for i in range(size):
        samples, intervals, taken = _refine_point(
            i, rows, start, pinned, w_r[i], lift_period_s[i], min_w_r, threshold_j, rtol, flight_cap, mu, buf
        )
        p_table, p_phase, lo, hi, ra, rb, score = buf[0], buf[2], buf[3], buf[4], buf[5], buf[6], buf[7]
        node_weight[:samples] = 0.0
        for k in range(intervals):  # the trapezoid's node weights: half of each interval to either end
            half = 0.5 * (hi[k] - lo[k])
            node_weight[ra[k]] += half
            node_weight[rb[k]] += half
            error[i] += score[k]
        error[i] *= rtol
        used[i] = taken
        if filled + samples > out.shape[0]:  # double the output
            grown = np.empty((2 * (filled + samples), out.shape[1]))
            grown[:filled] = out[:filled]
            out = grown
        block = out[filled : filled + samples]
        block[:, :_PHASE] = p_table[:samples]
        block[:, _PHASE], block[:, _WEIGHT], block[:, _OWNER] = p_phase[:samples], node_weight[:samples], i
        filled += samples
    return out[:filled], used, error


def phase_integral(
    rows: FloatArray,
    theta_start_rad: FloatArray,
    pinned: np.ndarray,
    lift_period_s: FloatArray,
    min_omega_r_rad_s: float,
    threshold_j: float,
    rtol: float,
    flight_cap_s: float,
    friction: float,
) -> tuple[FloatArray, FloatArray, FloatArray, np.ndarray, FloatArray, FloatArray]:
    """Every point's samples by the adaptive rule: (table, phase, weight, owner, used, error).

    ``rows`` (points, len(PARAMS)), rod 0 at its start angle ``theta_start_rad``, ``pinned`` where no phase can
    detach, ``lift_period_s`` 2π/(lift strokes · ω_v) a point (the lift-cycle test); samples with rotary speed
    below ``min_omega_r_rad_s`` count nothing. ``table``: one :data:`TELEMETRY` row a sample, point by point in
    the order taken; ``phase`` its lift phase (rad); ``weight`` its trapezoid weight (rad: the half widths of the
    two intervals it ends); ``owner`` its point; ``used`` the samples a point took; ``error`` rtol × the sum
    of its intervals' scores (the estimate of the larger of the power's relative and the shares' absolute error).
    """
    table = np.ascontiguousarray(rows, dtype=np.float64)
    size = table.shape[0]
    start = np.ascontiguousarray(theta_start_rad, dtype=np.float64).reshape(size)
    flags = np.ascontiguousarray(pinned, dtype=np.bool_).reshape(size)
    w_r = np.ascontiguousarray(table[:, _WR])
    lift = np.ascontiguousarray(lift_period_s, dtype=np.float64).reshape(size)
    args = (float(min_omega_r_rad_s), float(threshold_j), float(rtol), float(flight_cap_s), float(friction))
    samples, used, error = _integrate(table, start, flags, w_r, lift, *args)
    owner = samples[:, _OWNER].astype(np.int64)
    return samples[:, :_PHASE], samples[:, _PHASE], samples[:, _WEIGHT], owner, used, error


__all__ = ["FINEST_PHASE_RAD", "FIRST_PHASES", "MAX_CAM_PHASES", "phase_integral"]

"""Level (b): the node telemetry's cam-phase samples with the no-slip check of the carried rod (slip.py, telemetry.py).

Sample k of a scene: rod 0 from its start angle with lift phase 2πk/K, its one-rod event
(:mod:`.events`), and the first time the carried ride from the bottom needs a wall traction
|F_t| > μN (:func:`_slip_onset`, two trig sums μN/m ∓ F_t/m, each searched by certified safe steps,
:func:`_margin_first_zero`). One scene (:func:`telemetry_samples`), a batch of scenes at K even phases
(:func:`telemetry_batch`) or samples at chosen phases (:func:`telemetry_at`, the adaptive cam-phase
integral's), no allocation per sample.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from millctl.physics.kernels.detach import (
    _falling_zero_windowed,
    _held_edge,
    _held_until,
    _product_arcs,
    _product_until,
    _revolution_s,
)
from millctl.physics.kernels.events import _event, _scratch
from millctl.physics.kernels.layout import (
    _A0,
    _G,
    _N,
    _O_ENERGY,
    _O_FOUND,
    _O_PARTNER,
    _O_T,
    _O_TD0,
    _O_TDEP,
    _O_THC,
    _O_THD,
    _R0,
    _RD,
    _RTOL,
    _STATE_COLUMNS,
    _T_COUNT,
    _TH0,
    _TRIG_COLUMNS,
    _TWO_PI,
    _WR,
    _WV,
    OUT,
    PARAMS,
    TELEMETRY,
    WALL,
    FloatArray,
)
from millctl.physics.kernels.trig import _set_margin_form, _set_term, _trig, _trig012, _trig_bound


@njit(cache=True, error_model="numpy")
def _slip_rows(p, theta0, mu, rows):  # type: ignore[no-untyped-def]
    """Rows 0, 1 of ``rows``: μN/m − F_t/m and μN/m + F_t/m of a rod carried at θ0 + ω_r t (slip.no_slip_check).

    N is the corrected law in both variants; F_t/m = g_eff cos θ (slip.traction_per_mass). The six terms
    μg cos(θ + π/2) ∓ g cos θ, and the cam's ±½ r_d ω_v² pairs at ω_v ∓ ω_r, merge by a cos x + b sin x =
    √(a² + b²) cos(x − atan2(b, a)) into three, the slow one first (as in N), so that the search skips the
    arc where the slow term alone keeps the margin positive (:func:`.detach._held_until`).
    """
    wr, wv, a0, g = p[_WR], p[_WV], p[_A0], p[_G]
    half = 0.5 * p[_RD] * wv * wv
    scale = math.sqrt(1.0 + mu * mu)
    friction_angle = math.atan(mu)  # μ ≥ 0: atan2(μ, ±1) and atan2(±1, μ) all follow from it
    for r in range(2):
        sign = -1.0 if r == 0 else 1.0
        lead = friction_angle if sign > 0.0 else math.pi - friction_angle  # atan2(μ, sign)
        turn = sign * (0.5 * math.pi - friction_angle)  # atan2(sign, μ)
        rows[r, 0], rows[r, _T_COUNT] = mu * p[_R0] * wr * wr, 3.0
        # μg cos(θ + π/2) + sign·g cos θ = g √(1 + μ²) cos(θ + atan2(μ, sign))
        _set_term(rows, r, 0, g * scale, wr, theta0 + lead)
        # ½ r_d ω_v² (μ cos y − sign·sin y), y = (ω_v − ω_r) t + α0 − θ0
        _set_term(rows, r, 1, half * scale, wv - wr, a0 - theta0 + turn)
        # −½ r_d ω_v² (μ cos y + sign·sin y), y = (ω_v + ω_r) t + α0 + θ0
        _set_term(rows, r, 2, -half * scale, wv + wr, a0 + theta0 - turn)
        # the same sum as μ r0 ω_r² − g_eff (μ sin θ − sign·cos θ), g_eff = g − r_d ω_v² sin α: its product form
        _set_margin_form(rows, r, 2.0 * half, theta0, wv, a0, g, mu, -sign)
    return rows


_SAFE_STEPS = 48
"""Steps of :func:`_margin_first_zero` before it hands the rest of the arc to the windowed search."""


_LOOK_AHEAD = 4.0
"""How far past the global-curvature step (in those steps) :func:`_local_safe_step` looks."""


@njit(cache=True, error_model="numpy")
def _local_safe_step(m, dm, d2m, curvature_max, jerk_max, reach):  # type: ignore[no-untyped-def]
    """A step in (0, reach] over which m > 0 is certified from m, m′, m″ at its start and |m‴| ≤ ``jerk_max``.

    On [t, t + reach] m″ ≥ m″(t) − jerk_max·reach, and m″ ≥ −``curvature_max`` everywhere, so with
    d = max(0, min(curvature_max, jerk_max·reach − m″(t))) m(t + h) ≥ m + m′h − ½dh², positive for h below
    2m / (√(m′² + 2dm) − m′) (all of ``reach`` when d = 0 and m′ ≥ 0).
    """
    deficit = max(0.0, min(curvature_max, jerk_max * reach - d2m))
    root = math.sqrt(dm * dm + 2.0 * deficit * m) - dm
    if root <= 0.0:
        return reach
    return min(reach, 2.0 * m / root)


@njit(cache=True, error_model="numpy")
def _margin_first_zero(p, st, tr, i, t_end):  # type: ignore[no-untyped-def]
    """First zero in [0, t_end] of margin row i (m(0) > 0), by certified safe steps; inf: none.

    With M = Σ|a_k| w_k² ≥ |m''|, m(t + h) ≥ m + m' h − ½ M h² > 0 for h < 2m / (√(m'² + 2Mm) − m'), so
    each step lands short of the first zero (never past it) and near it becomes a Newton step; the arcs
    that the slow term alone or the product bound keep positive are skipped (:func:`.detach._held_until`,
    :func:`.detach._product_until`). A step below the root finder's resolution ends in one Newton step, the
    zero to rounding (as the windowed search's Brent finds it, ~1e-14 s apart); a ride that grazes zero
    without crossing goes to the windowed search after :data:`_SAFE_STEPS` steps. The product bound starts
    the steps at the end of the arc no cam phase can reach zero in, so few steps remain to the first zero.
    """
    curvature_max, jerk_max = _trig_bound(tr, i, 2), _trig_bound(tr, i, 3)
    edge, arcs = _held_edge(tr, i), _product_arcs(tr, i)
    t = max(0.0, _held_until(tr, i, 0.0, edge), _product_until(tr, i, 0.0, arcs))
    for _ in range(_SAFE_STEPS):
        if t >= t_end:
            return math.inf
        m, dm, d2m = _trig012(tr, i, t, 1.0)
        if m <= 0.0:
            return t
        h = 2.0 * m / (math.sqrt(dm * dm + 2.0 * curvature_max * m) - dm)
        if dm < 0.0 and h <= 4.0 * _RTOL * t:
            return t + m / -dm
        h = max(h, _local_safe_step(m, dm, d2m, curvature_max, jerk_max, _LOOK_AHEAD * h))
        t += h
        t = max(t, _held_until(tr, i, t, edge), _product_until(tr, i, t, arcs))
    return _falling_zero_windowed(p, st, tr, i, 1.0, t, t_end) if t < t_end else math.inf


@njit(cache=True, error_model="numpy")
def _slip_onset(p, theta0, mu, t_end, rows, st):  # type: ignore[no-untyped-def]
    """First time in [0, t_end] at which the carried rod needs |F_t| > μN (0: at once; inf: never).

    The second margin is searched only up to the first one's onset: a later zero of it cannot be the first.
    ``rows``: a (2, trig columns) work array; ``st``: a zeroed (1, state columns) one (unused by the search).
    """
    tr = _slip_rows(p, theta0, mu, rows)
    if _trig(tr, 0, 0.0, 0, 1.0) <= 0.0 or _trig(tr, 1, 0.0, 0, 1.0) <= 0.0:
        return 0.0
    onset = math.inf
    for r in range(2):
        horizon = min(t_end, onset)
        if horizon > 0.0:
            onset = min(onset, _margin_first_zero(p, st, tr, r, horizon))
    return onset


@njit(cache=True, error_model="numpy")
def _samples_into(rows, theta_start, pinned, scene, lift_phase, flight_cap, mu, out, work):  # type: ignore[no-untyped-def]
    """Telemetry samples into ``out`` (one row of :data:`TELEMETRY` each), no allocation.

    Sample s: scene ``scene[s]`` (its row of ``rows``, start angle and pinned flag), rod 0 from its start angle
    with the cam's lift phase ``lift_phase[s]`` (rad) at that moment.
    ``work``: (event row, _scratch, scene row, bottom scene row, slip rows, slip state) from :func:`_telemetry_work`.
    """
    ev, scratch, p, pb, slip_tr, slip_st = work
    out[:, :] = math.nan
    for s in range(scene.shape[0]):
        i = scene[s]
        theta0, stuck = theta_start[i], pinned[i]
        p[:] = rows[i]
        p[_TH0], p[_A0] = theta0, lift_phase[s]
        arc_end = _revolution_s(p)
        lead = (theta0 + 0.5 * math.pi) / p[_WR] if not stuck else 0.0
        if stuck:
            out[s, 0], out[s, 1] = 0.0, 0.0
        else:
            _event(p, False, math.inf, flight_cap, 0.0, ev, scratch)
            detached = ev[_O_TD0] == ev[_O_TD0]  # not nan
            out[s, 0], out[s, 1] = ev[_O_FOUND], 1.0 if detached else 0.0
            if ev[_O_FOUND] == 1.0:
                arc_end = ev[_O_TDEP]
                out[s, 2], out[s, 3], out[s, 4] = ev[_O_TDEP], ev[_O_THD], ev[_O_ENERGY]
                out[s, 5], out[s, 6] = ev[_O_T] - ev[_O_TDEP], 1.0 if ev[_O_PARTNER] == WALL else 0.0
                out[s, 7] = ev[_O_THC]
            elif detached:
                arc_end = ev[_O_TD0]
        # the carriage from the bottom: the same ride with the cam phase shifted back by ω_v·lead
        pb[:] = p
        pb[_TH0], pb[_A0] = -0.5 * math.pi, p[_A0] - p[_WV] * lead
        onset = _slip_onset(pb, -0.5 * math.pi, mu, arc_end + lead, slip_tr, slip_st)
        if onset < math.inf:
            out[s, 8] = onset
            out[s, 9] = (-0.5 * math.pi + p[_WR] * onset + math.pi) % _TWO_PI - math.pi


@njit(cache=True, error_model="numpy")
def _even_phases(scenes, phases):  # type: ignore[no-untyped-def]
    """Scene index and lift phase 2πk/K of every sample of ``scenes`` scenes at K even phases, scene by scene."""
    scene = np.empty(scenes * phases, dtype=np.int64)
    lift_phase = np.empty(scenes * phases)
    for i in range(scenes):
        for k in range(phases):
            scene[i * phases + k], lift_phase[i * phases + k] = i, _TWO_PI * k / phases
    return scene, lift_phase


@njit(cache=True, error_model="numpy")
def _telemetry_work(n_max):  # type: ignore[no-untyped-def]
    """The work arrays of :func:`_samples_into` for scenes of up to n_max rods (made once per batch)."""
    return (
        np.empty(len(OUT)),
        _scratch(n_max),
        np.empty(len(PARAMS)),
        np.empty(len(PARAMS)),
        np.zeros((2, _TRIG_COLUMNS)),
        np.zeros((1, _STATE_COLUMNS)),
    )


@njit(cache=True, error_model="numpy")
def _telemetry(p_base, theta_start, phases, flight_cap, mu, pinned):  # type: ignore[no-untyped-def]
    out = np.empty((phases, len(TELEMETRY)))
    scene, lift_phase = _even_phases(1, phases)
    rows, start, stuck = p_base.reshape(1, p_base.shape[0]), np.full(1, theta_start), np.full(1, pinned)
    _samples_into(rows, start, stuck, scene, lift_phase, flight_cap, mu, out, _telemetry_work(int(p_base[_N])))
    return out


def telemetry_samples(
    scene_row_: FloatArray, theta_start_rad: float, cam_phases: int, flight_cap_s: float, friction: float, pinned: bool
) -> FloatArray:
    """The node telemetry's K samples in one compiled call (columns :data:`TELEMETRY`).

    Sample k: rod 0 pinned at ``theta_start_rad`` with cam phase 2πk/K, its one-rod event
    (:func:`first_impacts`, ``rods="one"``) and the no-slip check of the same ride from the
    bottom (slip.no_slip_check); ``pinned``: no phase can detach, only the check, over one revolution.
    """
    result: FloatArray = _telemetry(
        np.ascontiguousarray(scene_row_, dtype=np.float64),
        float(theta_start_rad),
        int(cam_phases),
        float(flight_cap_s),
        float(friction),
        bool(pinned),
    )
    return result


@njit(cache=True, error_model="numpy")
def _telemetry_batch(rows, theta_start, pinned, phases, flight_cap, mu):  # type: ignore[no-untyped-def]
    out = np.empty((rows.shape[0] * phases, len(TELEMETRY)))
    work = _telemetry_work(int(rows[:, _N].max()) if rows.shape[0] > 0 else 1)
    scene, lift_phase = _even_phases(rows.shape[0], phases)
    _samples_into(rows, theta_start, pinned, scene, lift_phase, flight_cap, mu, out, work)
    return out.reshape(rows.shape[0], phases, len(TELEMETRY))


def _scene_table(rows: FloatArray, theta_start_rad: FloatArray, pinned: NDArray[np.bool_]) -> tuple[Any, ...]:
    table = np.ascontiguousarray(rows, dtype=np.float64)
    if table.ndim != 2 or table.shape[1] != len(PARAMS):
        raise ValueError(f"rows must have shape (scenes, {len(PARAMS)}), got {table.shape}")
    start = np.ascontiguousarray(theta_start_rad, dtype=np.float64).reshape(table.shape[0])
    flags = np.ascontiguousarray(pinned, dtype=np.bool_).reshape(table.shape[0])
    return table, start, flags


def telemetry_batch(
    rows: FloatArray,
    theta_start_rad: FloatArray,
    pinned: NDArray[np.bool_],
    cam_phases: int,
    flight_cap_s: float,
    friction: float,
) -> FloatArray:
    """:func:`telemetry_samples` of many scenes in one compiled call: shape (scenes, K, len(TELEMETRY)).

    ``rows`` (scenes, len(PARAMS)); ``theta_start_rad`` and ``pinned`` one per scene. The
    design studies' level (b) at K fixed phases (:mod:`millctl.studies.arrays`): no Python per scene.
    """
    table, start, flags = _scene_table(rows, theta_start_rad, pinned)
    result: FloatArray = _telemetry_batch(table, start, flags, int(cam_phases), float(flight_cap_s), float(friction))
    return result


@njit(cache=True, error_model="numpy")
def _telemetry_at(rows, theta_start, pinned, scene, lift_phase, flight_cap, mu):  # type: ignore[no-untyped-def]
    out = np.empty((scene.shape[0], len(TELEMETRY)))
    work = _telemetry_work(int(rows[:, _N].max()) if rows.shape[0] > 0 else 1)
    _samples_into(rows, theta_start, pinned, scene, lift_phase, flight_cap, mu, out, work)
    return out


def telemetry_at(
    rows: FloatArray,
    theta_start_rad: FloatArray,
    pinned: NDArray[np.bool_],
    scene_index: NDArray[np.int64],
    lift_phase_rad: FloatArray,
    flight_cap_s: float,
    friction: float,
) -> FloatArray:
    """Samples at chosen lift phases, shape (S, len(TELEMETRY)): sample s, ``scene_index[s]`` at ``lift_phase_rad[s]``.

    The scenes as :func:`telemetry_batch`'s; a sample at phase 2πk/K is bit for bit that call's sample k
    (the adaptive cam-phase integral of :mod:`millctl.studies.phase_integral` places its phases this way).
    """
    table, start, flags = _scene_table(rows, theta_start_rad, pinned)
    index = np.ascontiguousarray(scene_index, dtype=np.int64).ravel()
    phase = np.ascontiguousarray(lift_phase_rad, dtype=np.float64).ravel()
    if index.shape != phase.shape:
        raise ValueError(f"scene_index {index.shape} and lift_phase_rad {phase.shape} must have one shape")
    if index.size and (int(index.min()) < 0 or int(index.max()) >= table.shape[0]):
        raise ValueError(f"scene_index must lie in [0, {table.shape[0]}), got {int(index.min())}..{int(index.max())}")
    result: FloatArray = _telemetry_at(table, start, flags, index, phase, float(flight_cap_s), float(friction))
    return result


__all__ = ["telemetry_at", "telemetry_batch", "telemetry_samples"]

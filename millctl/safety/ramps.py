"""The ramp planner: moves between speed pairs whose every instant stays inside the envelope.

A move from A = (ω_r0, ω_v0) to B = (ω_r1, ω_v1) is planned as three
one-axis ramps through a safe corridor (docs/safety.md#whole-ramp-check):

1. ω_r down (or hold) to ω_r,low at ω_v0,
2. ω_v from ω_v0 to ω_v1 at ω_r,low,
3. ω_r up (or hold) to ω_r1 at ω_v1,

with ω_r,low = min(ω_r0, ω_r1, min over [ω_v0, ω_v1] of the envelope limit).
Every segment is inside: ramps 1 and 3 run below an endpoint that is inside
at a fixed ω_v; ramp 2 runs below the lowest limit on its way. Where the
limit rises with ω_v (printed eq. 9) this raises ω_v before ω_r and lowers
ω_r before ω_v; where it falls, the other way round — with no special case.

Every law of :mod:`millctl.physics.limits` is unimodal in ω_v, so the lowest
limit over an interval lies at an end; the planner still checks a grid in
between, so a future law that is not unimodal is handled conservatively.

Setpoints travel on the wire with a finite resolution: 0.1 rpm on millbus, a
CiA 402 drive's velocity unit on that backend (:mod:`millctl.safety.grid`,
chosen per axis from the configuration). Endpoints are snapped to that grid
and ω_r,low is rounded down onto it, so that a point on a ramp rounded by the
codec stays between the ramp's grid-aligned ends and inside.
Every planned move is then checked on what will be sent: every rounded pair
its segments can put on the wire (:mod:`millctl.safety.wire`), for every
path kind — a linear ramp that runs close to the limit can round outside.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from millctl.config.models import MillConfig
from millctl.safety.envelope import Envelope, InterlockRefused, Verdict
from millctl.safety.grid import AxisGrid, wire_grids
from millctl.safety.wire import Resolution, axis_grids, first_wire_violation

SETTLE_TIME_CONSTANTS = 5.0
"""The planner dwells this many drive time constants between one-axis ramps."""

INTERIOR_GRID = 65
"""Points at which the limit is also checked inside an ω_v sweep."""


@dataclass(frozen=True)
class SpeedPoint:
    """A pair of drive speeds (rpm)."""

    omega_r_rpm: float
    omega_v_rpm: float


STANDSTILL = SpeedPoint(0.0, 0.0)


@dataclass(frozen=True)
class Segment:
    """A linear ramp of one or both speeds between two instants (s, from the move's start)."""

    t0_s: float
    t1_s: float
    start: SpeedPoint
    end: SpeedPoint

    def at(self, t_s: float) -> SpeedPoint:
        """Speeds at time ``t_s`` (clamped to the segment)."""
        span = self.t1_s - self.t0_s
        f = 1.0 if span <= 0.0 else min(max((t_s - self.t0_s) / span, 0.0), 1.0)
        return SpeedPoint(
            self.start.omega_r_rpm + f * (self.end.omega_r_rpm - self.start.omega_r_rpm),
            self.start.omega_v_rpm + f * (self.end.omega_v_rpm - self.start.omega_v_rpm),
        )


@dataclass(frozen=True)
class Trajectory:
    """A planned move: consecutive segments from ``start`` to ``end``."""

    start: SpeedPoint
    end: SpeedPoint
    segments: tuple[Segment, ...]

    @property
    def duration_s(self) -> float:
        """Time the whole move takes (s)."""
        return self.segments[-1].t1_s if self.segments else 0.0

    def at(self, t_s: float) -> SpeedPoint:
        """Speeds at ``t_s`` seconds after the move began (the end once it is over)."""
        for segment in self.segments:
            if t_s <= segment.t1_s:
                return segment.at(t_s)
        return self.end

    def vertices(self) -> list[SpeedPoint]:
        """The corners of the path, start and end included."""
        return [self.start, *(s.end for s in self.segments)]

    def sample(self, dt_s: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Times (s), ω_r (rpm) and ω_v (rpm) every ``dt_s``, ends included."""
        n = max(2, math.ceil(self.duration_s / dt_s) + 1)
        times = np.linspace(0.0, self.duration_s, n)
        points = [self.at(float(t)) for t in times]
        return (
            times,
            np.array([p.omega_r_rpm for p in points]),
            np.array([p.omega_v_rpm for p in points]),
        )

    def min_margin_rpm(self, envelope: Envelope, dt_s: float = 0.05) -> float:
        """Smallest distance to the rotary limit along the move (rpm); standstill counts as +inf."""
        _, w_r, w_v = self.sample(dt_s)
        margins = np.where(w_r == 0.0, np.inf, envelope.omega_r_limit_rpm(w_v) - w_r)
        return float(np.min(margins))


class RampPlanner:
    """Plans moves and stops inside one envelope, on the wire's speed grid."""

    def __init__(
        self,
        envelope: Envelope,
        resolution_rpm: float = 0.1,
        settle_s: float = 0.0,
        *,
        grids: tuple[AxisGrid, AxisGrid] | None = None,
    ) -> None:
        if not resolution_rpm > 0.0:
            raise ValueError(f"resolution_rpm = {resolution_rpm} must be > 0")
        if not settle_s >= 0.0:
            raise ValueError(f"settle_s = {settle_s} must be ≥ 0")
        self.envelope = envelope
        self.grids: tuple[AxisGrid, AxisGrid] = grids or axis_grids(resolution_rpm)
        """The (rotary, vibration) wire grids every setpoint is snapped to (:mod:`millctl.safety.grid`)."""
        self.resolution_rpm = max(grid.step_rpm for grid in self.grids)
        """The coarser axis's grid step (rpm)."""
        self.settle_s = settle_s
        """Dwell after each one-axis ramp, so that a lagging drive reaches the corner first (s)."""

    @classmethod
    def from_config(cls, config: MillConfig, envelope: Envelope | None = None) -> RampPlanner:
        """The planner every part of millctl uses for a configured mill: its backend's wire grids, the drives' dwell.

        On CiA 402 drives each axis's grid is its drive's velocity unit (at
        least the millbus 0.1 rpm), so the pair the interlock checks is the
        pair the drives read (SAFETY 21, :func:`millctl.safety.grid.wire_grids`).
        """
        drives = config.drives
        settle_s = SETTLE_TIME_CONSTANTS * max(drives.rotary.time_constant_s, drives.vibration.time_constant_s)
        return cls(envelope or Envelope.from_config(config), settle_s=settle_s, grids=wire_grids(config))

    def snap(self, point: SpeedPoint) -> SpeedPoint:
        """Round a pair onto the wire grid (what the node or the drives will read)."""
        grid_r, grid_v = self.grids
        return SpeedPoint(grid_r.snap(point.omega_r_rpm), grid_v.snap(point.omega_v_rpm))

    def _floor(self, value_rpm: float) -> float:
        return self.grids[0].floor(value_rpm)

    def _grid_text(self) -> str:
        steps = {f"{grid.step_rpm:g}" for grid in self.grids}
        if len(steps) == 1:
            return f"{steps.pop()} rpm"
        return f"{self.grids[0].step_rpm:g} rpm (rotary) and {self.grids[1].step_rpm:g} rpm (vibration)"

    def lowest_limit_rpm(self, omega_v0_rpm: float, omega_v1_rpm: float) -> float:
        """The lowest enforced rotary limit over the ω_v interval (rpm)."""
        grid = np.linspace(omega_v0_rpm, omega_v1_rpm, INTERIOR_GRID)
        return float(np.min(self.envelope.omega_r_limit_rpm(grid)))

    def _rates(self, rotary_rpm_s: float | None, vibration_rpm_s: float | None) -> tuple[float, float]:
        """Ramp rates (rpm/s): the drives' maxima by default; refused when beyond them."""
        env = self.envelope
        rate_r = env.rotary_max_accel_rpm_s if rotary_rpm_s is None else rotary_rpm_s
        rate_v = env.vibration_max_accel_rpm_s if vibration_rpm_s is None else vibration_rpm_s
        verdict = env.check_rates(rate_r, rate_v)
        if not verdict.ok:
            raise InterlockRefused(verdict, "ramp")
        return rate_r, rate_v

    def plan(
        self,
        start: SpeedPoint,
        target: SpeedPoint,
        rotary_rate_rpm_s: float | None = None,
        vibration_rate_rpm_s: float | None = None,
        *,
        allow_outside_start: bool = False,
    ) -> Trajectory:
        """Plan a move; refuse (InterlockRefused) a target or rate outside the envelope."""
        env = self.envelope
        rate_r, rate_v = self._rates(rotary_rate_rpm_s, vibration_rate_rpm_s)
        a, b = self.snap(start), self.snap(target)
        verdict = env.check(b.omega_r_rpm, b.omega_v_rpm)
        if not verdict.ok:
            raise InterlockRefused(verdict, self._as_sent("target", target, b))
        start_verdict = env.check(a.omega_r_rpm, a.omega_v_rpm)
        if not start_verdict.ok and not allow_outside_start:
            raise InterlockRefused(start_verdict, "ramp start")
        r_low = min(a.omega_r_rpm, b.omega_r_rpm)
        if a.omega_v_rpm != b.omega_v_rpm:
            r_low = min(r_low, self._floor(self.lowest_limit_rpm(a.omega_v_rpm, b.omega_v_rpm)))
        corners = [a, SpeedPoint(r_low, a.omega_v_rpm), SpeedPoint(r_low, b.omega_v_rpm), b]
        corners = [p for i, p in enumerate(corners) if i == 0 or p != corners[i - 1]]
        segments: list[Segment] = []
        t = 0.0
        for i, (p, q) in enumerate(itertools.pairwise(corners)):
            duration = abs(q.omega_r_rpm - p.omega_r_rpm) / rate_r + abs(q.omega_v_rpm - p.omega_v_rpm) / rate_v
            segments.append(Segment(t, t + duration, p, q))
            t += duration
            if self.settle_s > 0.0 and i < len(corners) - 2:
                segments.append(Segment(t, t + self.settle_s, q, q))
                t += self.settle_s
        move = Trajectory(a, b, tuple(segments))
        if not allow_outside_start:
            self._check_wire(move, "ramp")
        return move

    def _check_wire(self, move: Trajectory, what: str) -> None:
        """Refuse a move any of whose wire-rounded setpoints would be outside (what the node would refuse)."""
        violation = first_violation(move, self.envelope, self.grids)
        if violation is not None:
            t_s, verdict = violation
            raise InterlockRefused(
                verdict, f"{what} at t = {t_s:.1f} s of {move.duration_s:.1f} s (as sent, rounded to "
                f"{self._grid_text()})"
            )

    def _as_sent(self, what: str, asked: SpeedPoint, sent: SpeedPoint) -> str:
        """``what``, and the pair as sent where the wire's grid moved it far enough to show."""
        if abs(asked.omega_r_rpm - sent.omega_r_rpm) < 0.05 and abs(asked.omega_v_rpm - sent.omega_v_rpm) < 0.05:
            return what
        return (f"{what} (as sent on the wire's grid of {self._grid_text()}: ω_r = {sent.omega_r_rpm:g} rpm, "
                f"ω_v = {sent.omega_v_rpm:g} rpm)")

    def plan_linear(
        self,
        start: SpeedPoint,
        target: SpeedPoint,
        rotary_rate_rpm_s: float | None = None,
        vibration_rate_rpm_s: float | None = None,
    ) -> Trajectory:
        """Both speeds together along the straight line, as an operator may write it.

        Refused when any instant of the line leaves the envelope, though both
        ends may be inside (the limit curve is not straight), or when a
        setpoint rounded onto the wire grid would.
        """
        rate_r, rate_v = self._rates(rotary_rate_rpm_s, vibration_rate_rpm_s)
        a, b = self.snap(start), self.snap(target)
        duration = max(abs(b.omega_r_rpm - a.omega_r_rpm) / rate_r, abs(b.omega_v_rpm - a.omega_v_rpm) / rate_v)
        move = Trajectory(a, b, (Segment(0.0, duration, a, b),) if a != b else ())
        self._check_wire(move, "linear ramp")
        return move

    def plan_stop(self, current: SpeedPoint) -> Trajectory:
        """The controlled stop (category 1) from wherever the mill is, at the drives' maximum rates."""
        return self.plan(current, STANDSTILL, allow_outside_start=True)


def first_violation(
    move: Trajectory, envelope: Envelope, resolution_rpm: Resolution = 0.1
) -> tuple[float, Verdict] | None:
    """The first instant (s) of a move whose setpoint as sent (rounded to ``resolution_rpm``) is outside.

    ``resolution_rpm`` is one grid step for both axes (rpm) or each axis's grid (:mod:`millctl.safety.grid`).

    Returns it with the verdict there; None when every pair the move can put on the wire is inside.
    """
    return first_wire_violation(
        [
            (s.t0_s, s.t1_s, (s.start.omega_r_rpm, s.start.omega_v_rpm), (s.end.omega_r_rpm, s.end.omega_v_rpm))
            for s in move.segments
        ],
        envelope,
        resolution_rpm,
    )


__all__ = [
    "STANDSTILL",
    "RampPlanner",
    "Segment",
    "SpeedPoint",
    "Trajectory",
    "first_violation",
]

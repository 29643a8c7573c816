"""Believe only what was commanded: the band the measured speeds must stay in, in every state.

Outside a stop, each drive's measured speed must stay below the highest
speed the controller commanded over the last *lag window* (the confirmation
bound ``interlock.command_confirm_s`` plus the drives' settle time, five
time constants), widened by the measurement tolerance. A drive above it runs
faster than anyone asked (runaway, forged setpoints, a lost stop); a drive
at rest through a whole window in which it was commanded to turn did not
take its setpoints.

During a stop (STOPPING, and TRIPPED after a trip's stop) the controller
commands standstill and the node ramps down along the planner's stop from
where it was. Each drive must then stay under the *stop ceiling*: the
controller's own plan of that stop, from the highest of the speeds commanded
over the lag window and the last measured ones, read one lag window late.
Once that plan has ended, the ceiling is standstill. A drive above it is not
stopping: the controller escalates to an E-stop. The node reports the stop
complete once its drives are within the measurement tolerance of rest, while
they still settle; so the ceiling keeps bounding them (beside what is
commanded afterwards) until it reaches standstill itself, rather than the
band dropping to standstill ± tolerance under a drive at 2.9 rpm whose
noisy sensor reads 3.6 (docs/safety.md#believe-only-what-was-commanded).

Above the band, ``interlock.debounce_samples`` consecutive samples count, as
for the envelope; at rest when commanded to turn, a whole lag window
(docs/safety.md#believe-only-what-was-commanded).
"""

from __future__ import annotations

from collections import deque

from millctl.safety import RampPlanner, SpeedPoint, Trajectory

AT_REST_TOLERANCES = 5.0
"""A drive at rest (≤ the tolerance) although every speed commanded over the window exceeds this many
tolerances did not take its setpoints (the node's own stall check uses the same threshold)."""


class SpeedExpectation:
    """What the measured speed pair may be, given what the controller commanded (rpm, s)."""

    def __init__(self, planner: RampPlanner, tolerance_rpm: float, window_s: float, debounce_samples: int) -> None:
        self.planner = planner
        self.tolerance_rpm = tolerance_rpm
        self.window_s = window_s
        self.debounce_samples = debounce_samples
        self._history: deque[tuple[float, float, float]] = deque()
        self.stop: Trajectory | None = None
        """The stop the drives must stay under, while one is under way."""
        self._stop_started_s = 0.0
        self._settling: tuple[Trajectory, float] | None = None
        """A stop the node reported done, and when it began: its ceiling bounds the drives until standstill."""
        self.outside_in_a_row = 0
        self.below_since_s: float | None = None

    def commanded(self, now_s: float, point: SpeedPoint) -> None:
        """Record the speed pair commanded at ``now_s`` (forget what is older than the window)."""
        history = self._history
        if history and history[-1][0] == now_s:
            history.pop()
        history.append((now_s, point.omega_r_rpm, point.omega_v_rpm))
        while len(history) > 1 and history[1][0] <= now_s - self.window_s:
            history.popleft()  # keep the one in force at the window's start

    def _span(self) -> tuple[float, float, float, float]:
        """(lowest ω_r, highest ω_r, lowest ω_v, highest ω_v) commanded over the window (rpm)."""
        if not self._history:
            return 0.0, 0.0, 0.0, 0.0
        r = [h[1] for h in self._history]
        v = [h[2] for h in self._history]
        return min(r), max(r), min(v), max(v)

    def begin_stop(self, now_s: float, measured: tuple[float, float] | None) -> Trajectory:
        """A stop begins (kept if one is under way): plan its ceiling from the highest recent speeds."""
        if self.stop is None:
            _, r_high, _, v_high = self._span()
            m_r, m_v = measured if measured is not None else (0.0, 0.0)
            start = SpeedPoint(max(r_high, m_r, 0.0), max(v_high, m_v, 0.0))
            self.stop = self.planner.plan_stop(start)
            self._stop_started_s = now_s
            self._settling = None
        return self.stop

    def end_stop(self) -> None:
        """The stop is over (the node reported it done, or a reset completed).

        Its ceiling stays an upper bound on the drives, beside what is
        commanded next, until the ceiling itself reaches standstill.
        """
        if self.stop is not None:
            self._settling = (self.stop, self._stop_started_s)
        self.stop = None

    def _settling_ceiling(self, now_s: float) -> SpeedPoint | None:
        """The ended stop's ceiling at ``now_s`` while it is above standstill (None after, or with no stop)."""
        if self._settling is None:
            return None
        stop, started_s = self._settling
        elapsed_s = now_s - started_s - self.window_s
        if elapsed_s >= stop.duration_s:
            self._settling = None
            return None
        return stop.at(max(elapsed_s, 0.0))

    @property
    def stop_bound_s(self) -> float:
        """How long the stop may take: its plan plus one lag window (s)."""
        return (self.stop.duration_s if self.stop is not None else 0.0) + self.window_s

    @property
    def stop_end_s(self) -> float:
        """When the stop ceiling reaches standstill: the stop's deadline (s)."""
        return self._stop_started_s + self.stop_bound_s

    def band(self, now_s: float) -> tuple[tuple[float, float], tuple[float, float]]:
        """The allowed (low, high) of ω_r and of ω_v at ``now_s`` (rpm), tolerance included."""
        tol = self.tolerance_rpm
        if self.stop is not None:
            ceiling = self.stop.at(max(now_s - self._stop_started_s - self.window_s, 0.0))
            return (-tol, ceiling.omega_r_rpm + tol), (-tol, ceiling.omega_v_rpm + tol)
        r_low, r_high, v_low, v_high = self._span()
        settling = self._settling_ceiling(now_s)
        if settling is not None:
            r_high, v_high = max(r_high, settling.omega_r_rpm), max(v_high, settling.omega_v_rpm)
        return (r_low - tol, r_high + tol), (v_low - tol, v_high + tol)

    def check(self, now_s: float, omega_r_rpm: float, omega_v_rpm: float) -> str | None:
        """Check one measured pair (rpm); the reason once it is judged outside, else None.

        Above the band counts after the debounce count of samples in a row
        (a drive faster than commanded is a hazard). A drive at rest though
        commanded to turn counts once that has lasted a whole lag window: it
        did not take its setpoints (a stall is diagnosed sooner by the
        node's own check, or trips on the envelope).
        """
        (r_low, r_high), (v_low, v_high) = self.band(now_s)
        above = omega_r_rpm > r_high or omega_v_rpm > v_high
        tol = self.tolerance_rpm
        turning = AT_REST_TOLERANCES * tol
        below = (omega_r_rpm <= tol and r_low + tol > turning) or (omega_v_rpm <= tol and v_low + tol > turning)
        self.outside_in_a_row = self.outside_in_a_row + 1 if above else 0
        if not below:
            self.below_since_s = None
        elif self.below_since_s is None:
            self.below_since_s = now_s
        if self.outside_in_a_row >= self.debounce_samples:
            judged = f"above it for {self.outside_in_a_row} samples in a row"
        elif self.below_since_s is not None and now_s - self.below_since_s >= self.window_s:
            judged = f"below it for {now_s - self.below_since_s:.1f} s: the node did not take its setpoints"
        else:
            return None
        what = "what was commanded" if self._settling is None else "what was commanded or the ended stop's ceiling"
        if self.stop is not None:
            what = "the stop ceiling"
        return (
            f"measured ω_r = {omega_r_rpm:.1f} rpm, ω_v = {omega_v_rpm:.1f} rpm is not {what} "
            f"(ω_r {max(r_low, 0.0):.1f}…{r_high:.1f} rpm, ω_v {max(v_low, 0.0):.1f}…{v_high:.1f} rpm over the "
            f"last {self.window_s:.1f} s: interlock.command_confirm_s + drive settle, tolerance "
            f"{self.tolerance_rpm:.1f} rpm); {judged}"
        )

    def reset(self) -> None:
        """Forget the debounce count."""
        self.outside_in_a_row = 0
        self.below_since_s = None


__all__ = ["SpeedExpectation"]

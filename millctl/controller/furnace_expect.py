"""Believe only what was commanded, for the furnace: the node's heater must follow the controller's target.

The controller's furnace target rides in the Setpoints frames (heater on,
setpoint °C). The node reports the setpoint its heater loop follows and
whether the heater is on in FurnaceTelemetry (10 Hz). As for the speeds
(:mod:`millctl.controller.expect`), the report must stay inside what was
commanded over the last *lag window* (``interlock.command_confirm_s``):

* **above** — the heater on although the controller commanded it off
  throughout the window, or a setpoint above the highest one commanded —
  is heat nobody asked for (a forged or a stale target, a node that did not
  take a lower one); ``interlock.debounce_samples`` reports in a row count;
* **below** — the heater off, or a setpoint under the lowest one commanded,
  while the controller commanded the heater on throughout the window — is a
  target the node did not take; it counts once it has lasted a whole window.

A heater the node turns off for a fault of its own is reported as that fault
in NodeStatus first (docs/safety.md#believe-only-what-was-commanded).
"""

from __future__ import annotations

from collections import deque

from millctl.protocol.messages import FurnaceTelemetry

WIRE_RESOLUTION_C = 0.1
"""The furnace setpoint's resolution on the wire (config/millbus.dbc: Setpoints.furnace_c, setpoint_c)."""
TOLERANCE_C = WIRE_RESOLUTION_C * (1.0 + 1e-6)
"""A reported setpoint within one grid step of what was commanded is believed (the 1e-6: float noise)."""


class FurnaceExpectation:
    """What the node's reported heater state and setpoint may be, given the targets commanded (°C, s)."""

    def __init__(self, window_s: float, debounce_samples: int) -> None:
        self.window_s = window_s
        self.debounce_samples = debounce_samples
        self._history: deque[tuple[float, float | None]] = deque()
        """(time, setpoint commanded), None where the heater was commanded off."""
        self.above_in_a_row = 0
        self.below_since_s: float | None = None

    def commanded(self, now_s: float, setpoint_c: float | None) -> None:
        """Record the furnace setpoint commanded at ``now_s`` (None: heater off); forget what is older."""
        history = self._history
        if history and history[-1][0] == now_s:
            history.pop()
        history.append((now_s, setpoint_c))
        while len(history) > 1 and history[1][0] <= now_s - self.window_s:
            history.popleft()  # keep the one in force at the window's start

    def _span(self, now_s: float) -> tuple[float | None, float | None]:
        """(lowest, highest) setpoint commanded over the window (°C).

        The highest is None when the heater was commanded off throughout; the
        lowest is None unless it was commanded on throughout the whole window.
        """
        on = [c for _, c in self._history if c is not None]
        highest = max(on) if on else None
        whole = self._history[0][0] <= now_s - self.window_s
        lowest = min(on) if on and len(on) == len(self._history) and whole else None
        return lowest, highest

    def check(self, now_s: float, report: FurnaceTelemetry) -> str | None:
        """Check one FurnaceTelemetry report; the reason once it is judged outside, else None."""
        if not self._history:
            return None
        low, high = self._span(now_s)
        tol = TOLERANCE_C
        above = report.heater_on and (high is None or report.setpoint_c > high + tol)
        below = low is not None and (not report.heater_on or report.setpoint_c < low - tol)
        self.above_in_a_row = self.above_in_a_row + 1 if above else 0
        if not below:
            self.below_since_s = None
        elif self.below_since_s is None:
            self.below_since_s = now_s
        if self.above_in_a_row >= self.debounce_samples:
            judged = f"above it for {self.above_in_a_row} reports in a row"
        elif self.below_since_s is not None and now_s - self.below_since_s >= self.window_s:
            judged = f"below it for {now_s - self.below_since_s:.1f} s: the node did not take its furnace target"
        else:
            return None
        shown = f"heater on at {report.setpoint_c:.1f} °C" if report.heater_on else "heater off"
        if high is None:
            commanded = "heater off"
        elif low is None:
            commanded = f"heater off or on at up to {high:.1f} °C"
        else:
            commanded = f"heater on at {low:.1f}…{high:.1f} °C"
        return (
            f"node reports {shown}, which is not what was commanded ({commanded} over the last "
            f"{self.window_s:.1f} s: interlock.command_confirm_s); {judged}"
        )

    def reset(self) -> None:
        """Forget the debounce count."""
        self.above_in_a_row = 0
        self.below_since_s = None


__all__ = ["TOLERANCE_C", "WIRE_RESOLUTION_C", "FurnaceExpectation"]

"""A rate bound over any window: how far a setpoint may move, however often it is sent.

A per-frame step limit scaled by the time since the last frame is not a rate
bound: it grants each frame a minimum allowance (a period, or a slack in rpm),
so a sender that sends faster walks the setpoint faster. A 100 Hz forger
under the node's old step limit (elapsed time floored at the 0.1 s setpoint
period) walked ω_r at 620 rpm/s where the drive's limit is 40 rpm/s.

:class:`SlewBudget` is a token bucket. Its allowance refills at
``rate_per_s`` up to ``burst``; each accepted step spends its size. For any
window [t₁, t₂] the accepted steps then sum to at most

    burst + rate_per_s · (t₂ − t₁)

so |x(t₂) − x(t₁)| ≤ burst + rate_per_s · (t₂ − t₁), whatever the number
of frames: sending more often buys nothing, waiting banks at most ``burst``.
"""

from __future__ import annotations

import math


class SlewBudget:
    """The allowance (in the setpoint's unit) of one axis: refills at ``rate_per_s``, holds at most ``burst``."""

    def __init__(self, rate_per_s: float, burst: float) -> None:
        if not (math.isfinite(rate_per_s) and rate_per_s > 0.0):
            raise ValueError(
                f"slew rate {rate_per_s!r}/s: must be finite and > 0 (docs/operations.md#node-side-checks)"
            )
        if not (math.isfinite(burst) and burst > 0.0):
            raise ValueError(f"slew burst {burst!r}: must be finite and > 0 (docs/operations.md#node-side-checks)")
        self.rate_per_s = rate_per_s
        self.burst = burst
        self._left = burst
        self._at_s = 0.0
        """When ``_left`` was last reckoned (s); any start time will do while the allowance is full."""

    def available(self, now_s: float) -> float:
        """The largest step allowed at ``now_s``: what was left, refilled since, at most ``burst``."""
        refill = self.rate_per_s * max(now_s - self._at_s, 0.0)
        return min(self.burst, self._left + refill)

    def allows(self, step: float, now_s: float) -> bool:
        """True when a step of this size (either sign) fits in the allowance at ``now_s``."""
        return abs(step) <= self.available(now_s)

    def spend(self, step: float, now_s: float) -> None:
        """Take an accepted step out of the allowance (a step larger than the allowance leaves none)."""
        self._left = max(self.available(now_s) - abs(step), 0.0)
        self._at_s = now_s

    def refill(self, now_s: float) -> None:
        """A full allowance from ``now_s`` (the setpoint was reset to a known state)."""
        self._left = self.burst
        self._at_s = now_s


__all__ = ["SlewBudget"]

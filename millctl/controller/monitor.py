"""The measured-speed interlock: each new measured pair is checked; N outside in a row trip.

An invalid measurement (not finite, or negative beyond the tolerance) trips at
once (docs/safety.md#measured-speed-interlock).
"""

from __future__ import annotations

import math

from millctl.safety import Envelope


class MeasuredSpeedMonitor:
    """Debounced envelope check of measured speed pairs."""

    def __init__(self, envelope: Envelope, debounce_samples: int) -> None:
        if debounce_samples < 1:
            raise ValueError(f"debounce_samples = {debounce_samples} must be ≥ 1")
        self.envelope = envelope
        self.debounce_samples = debounce_samples
        self.outside_in_a_row = 0

    def update(self, omega_r_rpm: float, omega_v_rpm: float) -> str | None:
        """Check one new measured pair; return the trip reason, or None while safe."""
        tolerance = self.envelope.measurement_tolerance_rpm
        if (
            not (math.isfinite(omega_r_rpm) and math.isfinite(omega_v_rpm))
            or min(omega_r_rpm, omega_v_rpm) < -tolerance
        ):
            return f"invalid speed measurement ω_r = {omega_r_rpm} rpm, ω_v = {omega_v_rpm} rpm"
        w_r, w_v = max(omega_r_rpm, 0.0), max(omega_v_rpm, 0.0)
        if self.envelope.allows_measured(w_r, w_v):  # the scalar path: every sample, ≤ 1 µs
            self.outside_in_a_row = 0
            return None
        self.outside_in_a_row += 1
        if self.outside_in_a_row < self.debounce_samples:
            return None
        verdict = self.envelope.check_measured(w_r, w_v)
        return (
            f"measured speeds outside the envelope for {self.outside_in_a_row} samples "
            f"(tolerance {tolerance:.1f} rpm): {verdict.reason()}"
        )

    def reset(self) -> None:
        """Forget the debounce count."""
        self.outside_in_a_row = 0


__all__ = ["MeasuredSpeedMonitor"]

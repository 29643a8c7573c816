"""The interlock envelope: the one place that says which operating points are allowed.

The envelope is ω_r ≤ (1 − margin)·ω_r,max(ω_v) under the configured law
(default: the paper's eq. 9), plus the drives' absolute speed and acceleration
limits and the furnace's temperature range. Standstill (ω_r = 0) is always
inside. The controller refuses, the planner plans, the TUI greys out and the
node rejects, all through :meth:`Envelope.check` (docs/safety.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from millctl.config.models import LimitLaw, MillConfig
from millctl.errors import InterlockError
from millctl.physics.limits import LimitParams, is_every_cycle_bound, omega_r_max, scalar_limit
from millctl.units import RPM_PER_RAD_S, rad_s_to_rpm, rpm_to_rad_s

DOC_REF = "docs/safety.md#setpoint-interlock"

_LAW_EQUATION = {
    LimitLaw.PAPER_EQ9: "paper eq. 9",
    LimitLaw.PAPER_EVERY_CYCLE: "paper eq. 8a at its worst phase",
    LimitLaw.CORRECTED_EVERY_PHASE: "corrected law, every phase",
    LimitLaw.CORRECTED_BEST_PHASE: "corrected law, best phase",
}

LAW_IN_WORDS = {
    LimitLaw.PAPER_EQ9: "paper eq. 9 as printed",
    LimitLaw.PAPER_EVERY_CYCLE: "paper, worst cam phase (rods detach every cycle)",
    LimitLaw.CORRECTED_EVERY_PHASE: "corrected law, worst cam phase",
    LimitLaw.CORRECTED_BEST_PHASE: "corrected law, best cam phase only (not every cycle)",
}
"""Each law in an operator's words, for legends (``millctl limits --plot``, the TUI's envelope view)."""


@dataclass(frozen=True)
class Refusal:
    """Why one quantity is outside the envelope: the value, the limit and the law."""

    quantity: str
    """Which quantity: ``omega_r``, ``omega_v``, ``furnace_temp`` or a rate."""
    value: float
    limit: float
    unit: str
    reason: str

    def __str__(self) -> str:
        return self.reason


@dataclass(frozen=True)
class Verdict:
    """The envelope's answer for one operating point."""

    refusals: tuple[Refusal, ...] = ()
    omega_r_limit_rpm: float = math.inf
    """The rotary limit at this ω_v, margin and absolute limit applied (rpm)."""
    margin_rpm: float = math.inf
    """ω_r limit minus ω_r (rpm): how far the point is from the edge; negative outside."""

    @property
    def ok(self) -> bool:
        """True when the point is inside the envelope."""
        return not self.refusals

    def reason(self) -> str:
        """All refusals as one sentence ('' when inside)."""
        return "; ".join(r.reason for r in self.refusals)


class InterlockRefused(InterlockError):
    """A request would leave the envelope; nothing was sent or changed."""

    def __init__(self, verdict: Verdict, what: str = "setpoint") -> None:
        self.verdict = verdict
        super().__init__(f"{what} refused by the interlock: {verdict.reason()} (see {DOC_REF})")


@dataclass(frozen=True)
class Envelope:
    """The allowed operating region of one configured mill."""

    params: LimitParams
    law: LimitLaw
    margin: float
    rotary_max_rpm: float
    vibration_max_rpm: float
    rotary_max_accel_rpm_s: float
    vibration_max_accel_rpm_s: float
    furnace_min_c: float
    furnace_max_c: float
    max_heating_rate_c_per_min: float
    measurement_tolerance_rpm: float = 0.0
    _law_text: str = field(init=False, repr=False)
    _keep: float = field(init=False, repr=False)
    """1 − margin, formed once."""
    _law_rad_s: Callable[[float], float] = field(init=False, repr=False, compare=False)
    """The configured law's ω_r,max(ω_v) in rad/s (:func:`~millctl.physics.limits.scalar_limit`), formed once."""

    def __post_init__(self) -> None:
        law_text = f"{self.law.value} ({_LAW_EQUATION[self.law]}), margin {self.margin:.0%}"
        object.__setattr__(self, "_law_text", law_text)
        object.__setattr__(self, "_keep", 1.0 - self.margin)
        object.__setattr__(self, "_law_rad_s", scalar_limit(self.law, self.params))

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the law's function (a closure), which :meth:`__setstate__` forms again."""
        return {k: v for k, v in self.__dict__.items() if k != "_law_rad_s"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        object.__setattr__(self, "_law_rad_s", scalar_limit(self.law, self.params))

    @classmethod
    def from_config(cls, config: MillConfig, law: LimitLaw | None = None) -> Envelope:
        """Build the envelope from a validated configuration (``law`` overrides the configured one)."""
        drives, furnace, interlock = config.drives, config.furnace, config.interlock
        return cls(
            params=LimitParams.from_config(config),
            law=interlock.law if law is None else law,
            margin=interlock.margin,
            rotary_max_rpm=drives.rotary.max_speed_rpm,
            vibration_max_rpm=drives.vibration.max_speed_rpm,
            rotary_max_accel_rpm_s=drives.rotary.max_accel_rpm_s,
            vibration_max_accel_rpm_s=drives.vibration.max_accel_rpm_s,
            furnace_min_c=furnace.min_setpoint_c,
            furnace_max_c=furnace.max_setpoint_c,
            max_heating_rate_c_per_min=furnace.max_heating_rate_c_per_min,
            measurement_tolerance_rpm=interlock.measurement_tolerance_rpm,
        )

    @property
    def description(self) -> str:
        """The law and margin in words, for logs and displays."""
        return self._law_text

    def law_limit_rpm(self, omega_v_rpm: ArrayLike) -> NDArray[np.float64]:
        """ω_r,max(ω_v) of the configured law, without margin (rpm)."""
        return rad_s_to_rpm(omega_r_max(self.law, self.params, rpm_to_rad_s(np.asarray(omega_v_rpm, float))))

    def omega_r_limit_rpm(self, omega_v_rpm: ArrayLike) -> NDArray[np.float64]:
        """The rotary limit the interlock enforces at ω_v (rpm): margin and absolute limit applied."""
        limit = (1.0 - self.margin) * self.law_limit_rpm(omega_v_rpm)
        return np.minimum(limit, self.rotary_max_rpm)

    def every_cycle(self, omega_v_rpm: ArrayLike) -> NDArray[np.bool_]:
        """True where the configured law is the every-cycle detachment bound at ω_v."""
        return is_every_cycle_bound(self.law, self.params, rpm_to_rad_s(np.asarray(omega_v_rpm, float)))

    def limit_rpm(self, omega_v_rpm: float) -> float:
        """Scalar :meth:`omega_r_limit_rpm` in plain ``math`` (rpm): margin and absolute limit applied."""
        law_rpm = self._law_rad_s(omega_v_rpm / RPM_PER_RAD_S) * RPM_PER_RAD_S
        return min(self._keep * law_rpm, self.rotary_max_rpm)

    def allows(self, omega_r_rpm: float, omega_v_rpm: float, tolerance_rpm: float = 0.0) -> bool:
        """The inside-test of one speed pair (rpm) in plain ``math``: the rule of :meth:`contains`, ≤ 1 µs.

        Bitwise the same verdict as :meth:`contains` and ``check(...).ok`` (tests/unit/test_limits.py).
        """
        if not (omega_r_rpm >= 0.0 and omega_v_rpm >= 0.0 and math.isfinite(omega_r_rpm + omega_v_rpm)):
            return False
        if omega_v_rpm > self.vibration_max_rpm + tolerance_rpm:
            return False
        if omega_r_rpm == 0.0:
            return True
        law_rpm = self._law_rad_s(omega_v_rpm / RPM_PER_RAD_S) * RPM_PER_RAD_S
        return omega_r_rpm <= min(self._keep * law_rpm, self.rotary_max_rpm) + tolerance_rpm

    def allows_measured(self, omega_r_rpm: float, omega_v_rpm: float) -> bool:
        """:meth:`allows` with the configured measurement tolerance."""
        return self.allows(omega_r_rpm, omega_v_rpm, self.measurement_tolerance_rpm)

    def contains(self, omega_r_rpm: ArrayLike, omega_v_rpm: ArrayLike, tolerance_rpm: float = 0.0) -> NDArray[np.bool_]:
        """Vectorised inside-test of speed pairs (rpm); the same rule as :meth:`check`."""
        w_r = np.asarray(omega_r_rpm, float)
        w_v = np.asarray(omega_v_rpm, float)
        speeds_ok = (w_r >= 0.0) & (w_v >= 0.0) & (w_v <= self.vibration_max_rpm + tolerance_rpm)
        detach_ok = (w_r == 0.0) | (w_r <= self.omega_r_limit_rpm(w_v) + tolerance_rpm)
        return np.asarray(speeds_ok & detach_ok & np.isfinite(w_r) & np.isfinite(w_v))

    def check(
        self,
        omega_r_rpm: float,
        omega_v_rpm: float,
        furnace_temp_c: float | None = None,
        *,
        tolerance_rpm: float = 0.0,
    ) -> Verdict:
        """Check one operating point; every violated bound becomes a :class:`Refusal`."""
        refusals: list[Refusal] = []
        for name, value in (("omega_r", omega_r_rpm), ("omega_v", omega_v_rpm)):
            if not math.isfinite(value) or value < 0.0:
                refusals.append(Refusal(name, value, 0.0, "rpm", f"{name} = {value} rpm must be a finite speed ≥ 0"))
        if refusals:
            return Verdict(tuple(refusals), omega_r_limit_rpm=0.0, margin_rpm=-math.inf)
        if omega_v_rpm > self.vibration_max_rpm + tolerance_rpm:
            refusals.append(
                Refusal(
                    "omega_v",
                    omega_v_rpm,
                    self.vibration_max_rpm,
                    "rpm",
                    f"ω_v = {omega_v_rpm:.1f} rpm exceeds the vibration drive's absolute limit "
                    f"{self.vibration_max_rpm:.1f} rpm (drives.vibration.max_speed_rpm)",
                )
            )
        law_limit = self._law_rad_s(omega_v_rpm / RPM_PER_RAD_S) * RPM_PER_RAD_S
        limit = min((1.0 - self.margin) * law_limit, self.rotary_max_rpm)
        if omega_r_rpm != 0.0 and omega_r_rpm > limit + tolerance_rpm:
            digits = 1 if f"{omega_r_rpm:.1f}" != f"{limit:.1f}" else 3  # show the difference
            if limit >= self.rotary_max_rpm:
                why = f"the rotary drive's absolute limit {self.rotary_max_rpm:.1f} rpm (drives.rotary.max_speed_rpm)"
            elif law_limit <= 0.0:
                why = f"no real limit at ω_v = {omega_v_rpm:.1f} rpm under {self._law_text}: only standstill is allowed"
            else:
                why = (
                    f"the limit {limit:.{digits}f} rpm at ω_v = {omega_v_rpm:.1f} rpm "
                    f"({1.0 - self.margin:.2f} × {law_limit:.1f} rpm, {self._law_text})"
                )
            refusals.append(
                Refusal("omega_r", omega_r_rpm, limit, "rpm", f"ω_r = {omega_r_rpm:.{digits}f} rpm exceeds {why}")
            )
        if furnace_temp_c is not None and not (self.furnace_min_c <= furnace_temp_c <= self.furnace_max_c):
            bound = self.furnace_min_c if furnace_temp_c < self.furnace_min_c else self.furnace_max_c
            refusals.append(
                Refusal(
                    "furnace_temp",
                    furnace_temp_c,
                    bound,
                    "°C",
                    f"furnace setpoint {furnace_temp_c:.1f} °C is outside "
                    f"[{self.furnace_min_c:.1f}, {self.furnace_max_c:.1f}] °C (furnace.min/max_setpoint_c)",
                )
            )
        return Verdict(tuple(refusals), omega_r_limit_rpm=limit, margin_rpm=limit - omega_r_rpm)

    def require(self, omega_r_rpm: float, omega_v_rpm: float, furnace_temp_c: float | None = None) -> Verdict:
        """Like :meth:`check`, but raise :class:`InterlockRefused` when outside."""
        verdict = self.check(omega_r_rpm, omega_v_rpm, furnace_temp_c)
        if not verdict.ok:
            raise InterlockRefused(verdict)
        return verdict

    def check_measured(self, omega_r_rpm: float, omega_v_rpm: float) -> Verdict:
        """Check a measured pair, allowing the configured measurement tolerance."""
        return self.check(omega_r_rpm, omega_v_rpm, tolerance_rpm=self.measurement_tolerance_rpm)

    def check_rates(self, rotary_rpm_s: float, vibration_rpm_s: float) -> Verdict:
        """Check ramp rates (rpm/s, magnitudes) against the drives' acceleration limits."""
        refusals = []
        for name, rate, bound, key in (
            ("omega_r_rate", rotary_rpm_s, self.rotary_max_accel_rpm_s, "drives.rotary.max_accel_rpm_s"),
            ("omega_v_rate", vibration_rpm_s, self.vibration_max_accel_rpm_s, "drives.vibration.max_accel_rpm_s"),
        ):
            if not math.isfinite(rate) or rate <= 0.0:
                refusals.append(Refusal(name, rate, bound, "rpm/s", f"{name} = {rate} rpm/s must be a finite rate > 0"))
            elif rate > bound:
                refusals.append(
                    Refusal(name, rate, bound, "rpm/s", f"{name} = {rate:.1f} rpm/s exceeds {bound:.1f} rpm/s ({key})")
                )
        return Verdict(tuple(refusals))

    def check_heating_rate(self, rate_c_per_min: float) -> Verdict:
        """Check a furnace ramp rate (°C/min, magnitude) against the furnace's maximum."""
        bound = self.max_heating_rate_c_per_min
        if math.isfinite(rate_c_per_min) and 0.0 < rate_c_per_min <= bound:
            return Verdict()
        return Verdict(
            (
                Refusal(
                    "heating_rate",
                    rate_c_per_min,
                    bound,
                    "°C/min",
                    f"heating rate {rate_c_per_min} °C/min must be in (0, {bound}] "
                    "(furnace.max_heating_rate_c_per_min)",
                ),
            )
        )


__all__ = ["DOC_REF", "LAW_IN_WORDS", "Envelope", "InterlockRefused", "Refusal", "Verdict"]

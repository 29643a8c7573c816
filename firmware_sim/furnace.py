"""The simulated furnace: a lumped thermal model, the node's temperature loop and its checks.

Thermal model (one lumped mass around the vial)::

    C dT/dt = P·u − G·(T − T_amb)

with C = ``furnace.heat_capacity_j_per_k`` (J/K), P = ``heater_power_w`` (W),
u ∈ [0, 1] the heater duty, G = ``loss_w_per_k`` (W/K) and T_amb =
``ambient_temp_c``. For a constant duty over a step it is integrated exactly:
T → T_eq + (T − T_eq)·exp(−G·dt/C), T_eq = T_amb + P·u/G.

The node's loop follows a ramped target that rises at most at
``max_heating_rate_c_per_min`` towards the setpoint, with a model-based
feed-forward (the power that holds the ramp: G·(T_r − T_amb) + C·dT_r/dt)
plus a PI correction. Checks, as Klipper's ``verify_heater``: over-temperature
(T ≥ ``over_temp_c``) and heater verification (full power for
``verify_period_s`` without a rise of ``verify_min_rise_c`` → fault).
"""

from __future__ import annotations

import math

from millctl.config.models import Furnace
from millctl.protocol.messages import NO_FAULTS, FaultFlag

CLOSED_LOOP_TIME_S = 20.0
"""Time constant the PI correction aims for (s): error × C / this is the corrective power."""
INTEGRAL_TIME_S = 80.0
"""Integral time of the PI correction (s)."""
FULL_POWER = 0.999
"""Duty at or above which the heater counts as at full power for verification."""


class FurnaceModel:
    """The furnace's temperature (°C), the heater loop and its latched-fault checks."""

    def __init__(self, furnace: Furnace, max_step_s: float) -> None:
        self.cfg = furnace
        self._max_step_s = max_step_s
        self.temp_c = furnace.ambient_temp_c
        """True (and measured) furnace temperature (°C)."""
        self.setpoint_c = furnace.ambient_temp_c
        """The last accepted setpoint (°C)."""
        self.ramp_c = furnace.ambient_temp_c
        """The rate-limited target the loop follows (°C)."""
        self.heater_on = False
        self.duty = 0.0
        """Heater duty commanded by the loop, 0 … 1."""
        self._integral_w = 0.0
        self.element_open = False
        """Injected: the element is open, no heat whatever the duty."""
        self.relay_welded = False
        """Injected: the heater relay is welded shut, full power whatever the loop (or the node) says."""
        self._verify_start: tuple[float, float] | None = None
        self._elapsed_s = 0.0

    def command(self, heater_on: bool, setpoint_c: float) -> None:
        """Take a new setpoint; switching the heater on starts the ramp at the present temperature."""
        if heater_on and not self.heater_on:
            self.ramp_c = self.temp_c
            self._integral_w = 0.0
        self.heater_on = heater_on
        self.setpoint_c = setpoint_c
        if not heater_on:
            self.heater_off()

    def heater_off(self) -> None:
        """Turn the heater off (duty 0, loop reset)."""
        self.heater_on = False
        self.duty = 0.0
        self._integral_w = 0.0
        self._verify_start = None

    def step(self, dt_s: float) -> None:
        """Advance loop and thermal model by ``dt_s`` (sub-stepped at the node tick)."""
        if dt_s <= 0.0:
            return
        steps = max(1, math.ceil(dt_s / self._max_step_s - 1e-9))
        for _ in range(steps):
            self._step(dt_s / steps)

    def _step(self, h: float) -> None:
        cfg = self.cfg
        self._elapsed_s += h
        if self.heater_on:
            # Ramped target: up at most at the maximum heating rate, down at once (cooling is passive).
            rate_c_s = cfg.max_heating_rate_c_per_min / 60.0
            previous = self.ramp_c
            self.ramp_c = min(self.setpoint_c, self.ramp_c + rate_c_s * h)
            ramp_rate_c_s = max(self.ramp_c - previous, 0.0) / h
            # Feed-forward: the power that holds the ramp, G·(T_r − T_amb) + C·dT_r/dt (W) ...
            feed_w = cfg.loss_w_per_k * (self.ramp_c - cfg.ambient_temp_c) + cfg.heat_capacity_j_per_k * ramp_rate_c_s
            # ... plus a PI correction on the error (W), with anti-windup by conditional integration.
            error_c = self.ramp_c - self.temp_c
            proportional_w = cfg.heat_capacity_j_per_k * error_c / CLOSED_LOOP_TIME_S
            demand = (feed_w + proportional_w + self._integral_w) / cfg.heater_power_w
            if 0.0 < demand < 1.0:
                self._integral_w += proportional_w * h / INTEGRAL_TIME_S
            self.duty = min(max(demand, 0.0), 1.0)
        else:
            self.duty = 0.0
        delivered = 1.0 if self.relay_welded else (0.0 if self.element_open else self.duty)
        # C dT/dt = P·u − G·(T − T_amb), exact for constant u over h.
        t_eq = cfg.ambient_temp_c + cfg.heater_power_w * delivered / cfg.loss_w_per_k
        self.temp_c = t_eq + (self.temp_c - t_eq) * math.exp(-cfg.loss_w_per_k * h / cfg.heat_capacity_j_per_k)
        self._verify(self._elapsed_s)

    def _verify(self, now_s: float) -> None:
        """Track the full-power window of heater verification."""
        if not self.heater_on or self.duty < FULL_POWER:
            self._verify_start = None
            return
        if self._verify_start is None:
            self._verify_start = (now_s, self.temp_c)

    def check(self) -> FaultFlag:
        """Faults of the furnace now: OVERTEMP and HEATER_VERIFY."""
        cfg = self.cfg
        faults = NO_FAULTS
        if not math.isfinite(self.temp_c) or self.temp_c >= cfg.over_temp_c:
            faults |= FaultFlag.OVERTEMP
        if self._verify_start is not None:
            start_s, start_c = self._verify_start
            if self._elapsed_s - start_s >= cfg.verify_period_s:
                if self.temp_c - start_c < cfg.verify_min_rise_c:
                    faults |= FaultFlag.HEATER_VERIFY
                else:
                    self._verify_start = (self._elapsed_s, self.temp_c)
        return faults


__all__ = ["CLOSED_LOOP_TIME_S", "FULL_POWER", "INTEGRAL_TIME_S", "FurnaceModel"]

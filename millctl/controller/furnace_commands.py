"""The furnace's part of the controller: its target checked whole, ramped at its heating rate, and its heater judged.

A split by concern of :class:`~millctl.controller.Controller` (see :mod:`.core`).
"""

from __future__ import annotations

from millctl.controller.core import ControllerCore
from millctl.controller.events import EventKind
from millctl.controller.states import ControllerState
from millctl.errors import InvalidInputError
from millctl.protocol import (
    FurnaceTelemetry,
)
from millctl.safety import InterlockRefused
from millctl.safety.commands import Operation

S = ControllerState


class FurnaceCommands(ControllerCore):
    """The furnace target, its heating rate, the setpoint on the wire, and the heater against it."""

    def set_furnace(
        self, temp_c: float | None, *, rate_c_per_min: float | None = None, source: str = "operator"
    ) -> None:
        """Set the furnace target (ramped at the heating rate); None turns the heater off."""
        if temp_c is not None:  # turning the heater off is allowed in every state
            self._require(Operation.FURNACE, "set the furnace", source)
        furnace = self._furnace_part(temp_c, rate_c_per_min, source)  # a rate with the heater off: refused
        if furnace is None:
            self.furnace_target_c = None
            self._emit(EventKind.COMMAND, source, "heater off")
            return
        self._apply_furnace(*furnace, source)

    def _furnace_part(
        self, temp_c: float | None, rate_c_per_min: float | None, source: str
    ) -> tuple[float, float] | None:
        """The furnace part of a command, checked: (target °C, heating rate °C/min), None when it has none.

        A heating rate with no target is refused, not ignored (docs/safety.md#setpoint-interlock).
        """
        if temp_c is None:
            if rate_c_per_min is not None:
                reason = (
                    f"heating rate {rate_c_per_min} °C/min given without a furnace target: there is nothing to "
                    "heat to, and the rate would be ignored; give the target with it, or leave the rate out"
                )
                self._emit(EventKind.REFUSAL, source, reason, heating_rate_c_per_min=rate_c_per_min)
                raise InvalidInputError(reason)
            return None
        return temp_c, self._check_furnace(temp_c, rate_c_per_min, source)

    def _check_furnace(self, temp_c: float, rate_c_per_min: float | None, source: str) -> float:
        """Check a furnace target and heating rate (°C, °C/min); return the rate in force, or refuse."""
        rate = self.config.furnace.max_heating_rate_c_per_min if rate_c_per_min is None else rate_c_per_min
        for verdict in (self.envelope.check(0.0, 0.0, temp_c), self.envelope.check_heating_rate(rate)):
            if not verdict.ok:
                self._emit(EventKind.REFUSAL, source, verdict.reason(), temp_c=temp_c)
                raise InterlockRefused(verdict, "furnace setpoint")
        return rate

    def _apply_furnace(self, temp_c: float, rate_c_per_min: float, source: str) -> None:
        if self.furnace_target_c is None:  # ramp from where the furnace is
            furnace = self.furnace
            self.furnace_setpoint_c = furnace.temp_c if furnace is not None else self.config.furnace.ambient_temp_c
        self.furnace_target_c = temp_c
        self.heating_rate_c_per_min = rate_c_per_min
        self._emit(
            EventKind.COMMAND, source, f"furnace to {temp_c:.1f} °C at {rate_c_per_min:.1f} °C/min", temp_c=temp_c
        )

    def _furnace_command(self) -> float | None:
        """The furnace setpoint the Setpoints frames carry now (°C, on the wire's grid); None: heater off."""
        if self.state in (S.ARMED, S.RUNNING) and self.furnace_target_c is not None:
            return round(self.furnace_setpoint_c, 1)
        return None

    def _on_furnace(self, report: FurnaceTelemetry) -> None:
        """Check the node's heater against the furnace targets commanded (in every state but DISCONNECTED)."""
        if self.state is S.DISCONNECTED:
            return
        reason = self.furnace_expectation.check(self.clock.now(), report)
        if reason is not None:
            self.furnace_expectation.reset()
            self._uncommanded(reason)


__all__ = ["FurnaceCommands"]

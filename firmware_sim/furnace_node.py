"""The millbus node in its furnace-only mode: the furnace beside CiA 402 drives, on a CAN channel of its own.

The same wire as the full node (``config/millbus.dbc``: E2E counter and CRC,
the heartbeat's challenge, the E-stop at 0x000), the same state machine
(ARM, STOP, RESET, E-stop, the watchdog) and the same furnace with its checks
and faults; but no drives: it neither expects nor checks the drive speeds of
a Setpoints frame (the controller sends zeros), it sends no DriveTelemetry and
no PhysicsTelemetry, and it never reports RUNNING (docs/deployment.md,
"A furnace beside the drives: a second CAN channel").
"""

from __future__ import annotations

from firmware_sim.node import Node
from millctl.protocol import (
    Decoded,
    DriveTelemetry,
    MillMessage,
    NodeState,
    PhysicsTelemetry,
    RefusalCode,
    Setpoints,
)
from millctl.safety.commands import NODE_SETPOINTS_IN


class FurnaceNode(Node):
    """The furnace-only millbus node (``python -m firmware_sim --furnace-only``; the embedded CiA 402 mill's)."""

    UNSENT: tuple[type[MillMessage], ...] = (DriveTelemetry, PhysicsTelemetry)

    def _setpoints(self, decoded: Decoded, fresh: bool, now: float) -> None:
        """The furnace's part of a fresh Setpoints in ARMED (or STOPPING); its drive speeds are not read."""
        message = decoded.message
        if not isinstance(message, Setpoints) or not fresh:
            self._refuse(RefusalCode.E2E, "setpoints with a bad CRC or stale counter")
            return
        if self._state not in NODE_SETPOINTS_IN:
            refusal = {NodeState.DISABLED: RefusalCode.NOT_ARMED, NodeState.FAULT: RefusalCode.FAULT_LATCHED}.get(
                self._state, RefusalCode.WRONG_STATE
            )
            self._refuse(refusal, f"setpoints {message}")
            return
        self.furnace.command(message.heater_on, message.furnace_c)
        self._refreshed_s = now
        self._last_setpoint = message

    def _checks(self, now: float, dt: float) -> None:
        """The furnace's checks, the watchdog and the link; a stop completes at once (nothing turns)."""
        faults = self._link_and_furnace_faults(now)
        if faults:
            self._latch(faults, f"checks: {faults!r}", now)
        if self.motion.stop is not None:
            self.motion.reset(now)
            if self._state is NodeState.STOPPING:
                self._set_state(NodeState.ARMED, "controlled stop complete (furnace only: nothing turns)")


__all__ = ["FurnaceNode"]

"""How the controller reads the node's reports: its state changes judged, a reset carried out, measured speeds checked.

A split by concern of :class:`~millctl.controller.Controller` (see :mod:`.core`):
any node state change the controller did not command trips
(docs/safety.md#every-command-confirmed), a reset completes only on the
node's DISABLED with its causes cleared.
"""

from __future__ import annotations

import logging

from millctl.controller.core import RESET_TIMEOUT_S, STANDSTILL_RPM, ControllerCore
from millctl.controller.events import EventKind
from millctl.controller.states import ControllerState
from millctl.protocol import (
    CommandCode,
    DriveTelemetry,
    FaultCode,
    FaultFlag,
    NodeState,
    NodeStatus,
)
from millctl.safety.commands import Operation, node_change_commanded

log = logging.getLogger(__name__)

S = ControllerState


class NodeReports(ControllerCore):
    """NodeStatus and DriveTelemetry as the controller judges them, and the reset procedure."""

    def reset(self, source: str = "operator") -> None:
        """Clear a latched trip: only with fresh telemetry and both drives at standstill."""
        self._require(Operation.RESET, "reset", source)
        now = self.clock.now()
        stale = self.tracker.stale(now)
        if stale:
            self._refuse(source, f"reset refused: {'; '.join(stale)}")
        measured = self.measured
        if measured is None or max(abs(measured.rotary_rpm), abs(measured.vibration_rpm)) > STANDSTILL_RPM:
            shown = "unknown" if measured is None else f"{measured.rotary_rpm:.1f}/{measured.vibration_rpm:.1f} rpm"
            self._refuse(source, f"reset refused: drives not at standstill (measured {shown})")
        self.tracker.reset_links()
        self.monitor.reset()
        self._reset_pending = True
        self._reset_source = source
        self._reset_sent = None
        self._reset_until_s = now + RESET_TIMEOUT_S
        self._emit(EventKind.COMMAND, source, "reset requested")
        self._advance_reset(self.node_status)

    def _advance_reset(self, node: NodeStatus | None) -> None:
        """Send what the node's state needs for a pending reset: RESET in FAULT, DISARM in ARMED (once each)."""
        if node is None:
            return
        wanted = {NodeState.FAULT: CommandCode.RESET, NodeState.ARMED: CommandCode.DISARM}.get(node.state)
        if wanted is not None and wanted is not self._reset_sent:
            self._reset_sent = wanted
            reason = f"clear latched trip: {self.trip_cause}" if wanted is CommandCode.RESET else "reset: to DISABLED"
            self._command(wanted, self._reset_source, reason)

    def _judge_node_change(self, node: NodeState) -> None:
        """Any node state change the controller did not command trips (E-stop where a stop was commanded).

        The one change judged against what the controller sent before rather
        than what it commands now: a RUNNING that answers its own order to run,
        which a STOP overtook (docs/safety.md#a-stop-overtaking-a-setpoint).
        """
        before, self._node_state = self._node_state, node
        now = self.clock.now()
        overtaken = node is NodeState.RUNNING and self.run_orders.explains_running(now)
        self.run_orders.reported(node)
        if before is None:  # first status (or first after losing the node): only a running node is suspect
            if node is NodeState.RUNNING and not self.moving_commanded and self.state is not S.DISCONNECTED:
                if overtaken:
                    self._stop_overtook_setpoint(now)
                    return
                self._uncommanded(f"node reports RUNNING, which the controller (state {self.state}) did not command")
            return
        if node_change_commanded(before, node, self.confirmations.in_flight(now), self.moving_commanded):
            return
        if overtaken:  # before is ARMED: any other report ends the order
            self._stop_overtook_setpoint(now)
            return
        restarted = ": the node restarted, or another sender commands it" if node is NodeState.DISABLED else (
            ": another sender commands the node"
        )
        self._uncommanded(
            f"node went {before.name} → {node.name}, which the controller (state {self.state}) did not command"
            + restarted
        )

    def _stop_overtook_setpoint(self, now: float) -> None:
        """The node ran on the controller's own setpoint, sent just before a STOP it has not taken yet: the stop holds.

        The STOP stays pending with its first deadline (pending again if a
        status from before the node took it had confirmed it), so RUNNING must
        end within the STOP's bound or the controller sends an E-stop; a
        controller that took that earlier status for the stop's end is
        STOPPING again, under the stop's ceiling.
        """
        stop_s = self.run_orders.stop_s
        self.confirmations.reopen(CommandCode.STOP, "controller", "the node ran on a setpoint sent before the STOP",
                                  stop_s)
        self._emit(
            EventKind.COMMAND,
            "controller",
            f"node RUNNING {now - stop_s:.2f} s after the STOP, on the setpoint sent before it (the node takes "
            "frames in order and has not taken the STOP yet): the stop holds, STOP pending "
            "(docs/safety.md#a-stop-overtaking-a-setpoint)",
        )
        if self.state is S.ARMED:
            self._expect_stop()
            self.machine.go(S.STOPPING, "node RUNNING on a setpoint sent before the STOP: the stop is not complete")

    def _on_node_status(self, status: NodeStatus) -> None:
        now = self.clock.now()
        self._judge_node_change(status.state)
        for confirmed in self.confirmations.confirm(status, now):
            log.debug("%s confirmed by node %s after %d send(s)", confirmed.code.name, status.state.name,
                      confirmed.sends)
        if self._estop_pending and FaultFlag.ESTOP in status.fault_bits:
            self._estop_pending = False
        state, node = self.state, status.state
        if state is S.TRIPPED and self._reset_pending:
            if node is NodeState.DISABLED and not status.fault_bits:
                self._reset_pending = False
                self._disarm_pending = False  # a DISARM lost before the trip is over: this one was the reset's
                self.trip_cause = ""
                self.expectation.end_stop()
                self.machine.go(S.DISABLED, "reset complete: node DISABLED, causes cleared")
            else:
                self._advance_reset(status)
            return
        if node is NodeState.FAULT:
            if state is S.TRIPPED:
                return
            cause = FaultCode(status.first_fault).name
            detail = self.drives.fault_detail()
            self._trip(f"node fault {cause} (fault bits {status.fault_bits!r})" + (f": {detail}" if detail else ""),
                       "node")
            return
        if state is S.DISCONNECTED:
            if node is NodeState.DISABLED:
                self.machine.go(S.DISABLED, "node seen, DISABLED")
            else:
                self._trip(f"node found in state {node.name} at connect: expected DISABLED", "node")
        elif state is S.DISABLED and node is NodeState.ARMED:
            self.machine.go(S.ARMED, "node ARMED")
        elif state is S.ARMED and node is NodeState.RUNNING:
            self.machine.go(S.RUNNING, "node RUNNING")
        elif state is S.STOPPING and node is NodeState.ARMED:
            self.expectation.end_stop()
            self.machine.go(S.ARMED, "controlled stop complete")
        elif state in (S.ARMED, S.STOPPING) and node is NodeState.DISABLED and self._disarm_pending:
            self._disarm_pending = False  # DISARM, then maybe a STOP it overtook (a no-op at rest): both confirmed
            self.expectation.end_stop()
            self.machine.go(S.DISABLED, "node DISABLED (disarmed)" if state is S.ARMED else
                            "node DISABLED: it took the DISARM sent before the STOP (at rest, disabled)")
        elif state in (S.ARMED, S.RUNNING, S.STOPPING) and node is NodeState.DISABLED:
            self._trip(f"node reports DISABLED while the controller is {state} with no DISARM of its own pending: "
                       "the node restarted, or another sender disarmed it", "node")

    def _on_measured(self, measured: DriveTelemetry) -> None:
        """Check a measured pair: the envelope (until tripped), and what was commanded (in every state)."""
        if self.state is S.DISCONNECTED:
            return
        if self.state is not S.TRIPPED:
            reason = self.monitor.update(measured.rotary_rpm, measured.vibration_rpm)
            if reason is not None:
                self._trip(reason)
        reason = self.expectation.check(self.clock.now(), measured.rotary_rpm, measured.vibration_rpm)
        if reason is not None:
            self.expectation.reset()
            self._uncommanded(reason)


__all__ = ["NodeReports"]

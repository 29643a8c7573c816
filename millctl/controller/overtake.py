"""A STOP that overtakes the controller's own order to run: the one node change it explains.

The node takes frames in the order they were sent. When the controller sends
its first nonzero Setpoints frame to a node it last saw ARMED, and a STOP
follows before the node's answer is back, the node takes the setpoint first
(ARMED → RUNNING, and a NodeStatus saying so), then the STOP. That RUNNING
reaches a controller that is already STOPPING (or TRIPPED, or ARMED again on
a status the node sent before it took the STOP), where, judged against what
is commanded *now*, it looks like a forgery (docs/safety.md#a-stop-overtaking-a-setpoint).

:class:`RunOrders` keeps what is needed to tell the two apart, and no more:
when the controller last ordered an ARMED node to run (a nonzero setpoint sent
while the node's last report was ARMED) and when it last issued a STOP. A
RUNNING report is explained by that order only while all of these hold:

* a STOP was issued at or after the order (without one, the ordinary rule
  applies: RUNNING needs a speed commanded now);
* the node has not reported anything but ARMED since the order (RUNNING
  answers the order, so it is explained once; STOPPING shows the node took a
  STOP, after which only a new setpoint, which the controller does not send,
  makes it run);
* the report comes within ``interlock.command_confirm_s`` of the order: the
  bound in which the node must act on, and report, what the controller sends.

The STOP stays in force: the controller holds it pending (again, if a status
from before it had confirmed it) with its first deadline, so the node must
leave RUNNING within the STOP's confirmation bound or the controller sends an
E-stop, and the measured speeds stay under the stop's ceiling throughout.
"""

from __future__ import annotations

import math

from millctl.protocol import NodeState


class RunOrders:
    """The controller's last order to run an ARMED node, and its last STOP (times in s, controller clock)."""

    def __init__(self, bound_s: float) -> None:
        self.bound_s = bound_s
        """How long after the order its RUNNING may still come back: ``interlock.command_confirm_s`` (s)."""
        self.ordered_s: float | None = None
        """When a nonzero setpoint last went to a node last reported ARMED, until the node answers (s)."""
        self.stop_s = -math.inf
        """When the controller last issued a STOP (s; −∞: never)."""

    def setpoints_sent(self, now_s: float, moving: bool, node: NodeState | None) -> None:
        """A Setpoints frame went out: ``moving`` when it asks for a speed other than standstill."""
        if moving and node is NodeState.ARMED:
            self.ordered_s = now_s

    def stop_sent(self, now_s: float) -> None:
        """The controller issued a STOP (an operator's, a recipe's, or a trip's)."""
        self.stop_s = now_s

    def explains_running(self, now_s: float) -> bool:
        """True when a RUNNING report now can be the node's answer to the order a STOP overtook."""
        ordered = self.ordered_s
        return ordered is not None and self.stop_s >= ordered and now_s - ordered <= self.bound_s

    def reported(self, node: NodeState) -> None:
        """The node reported ``node``: anything but ARMED answers (or ends) the order."""
        if node is not NodeState.ARMED:
            self.ordered_s = None


__all__ = ["RunOrders"]

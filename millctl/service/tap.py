"""A bus tap: the controller's bus, with every frame it sends or receives handed to the bus log.

The controller owns its bus and reads it itself, so a ``can.Notifier`` would
steal its frames; this wrapper logs on the way through instead. The log is
:class:`millctl.protocol.RotatingBusLog` (candump ``.log``, rotated by size).
"""

from __future__ import annotations

import logging
import time
from typing import Any

import can

log = logging.getLogger(__name__)


class TappedBus(can.BusABC):
    """Delegates to ``inner``; every frame sent or received also goes to ``listener``."""

    def __init__(self, inner: can.BusABC, listener: can.Listener) -> None:
        self.inner = inner
        self.listener = listener
        self.channel_info = f"tapped {inner.channel_info}"
        super().__init__(channel=getattr(inner, "channel", "") or "")

    def _log(self, msg: can.Message) -> None:
        try:
            self.listener.on_message_received(msg)
        except Exception as exc:  # the bus log must never stop the control loop, whatever the frame holds
            log.error("bus log write failed: %s", exc)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send through the inner bus, then log the frame (timestamped now if it had no time)."""
        self.inner.send(msg, timeout)
        if not msg.timestamp:
            msg.timestamp = time.time()
        self._log(msg)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        msg = self.inner.recv(timeout)
        if msg is not None:
            self._log(msg)
        return msg, True

    def shutdown(self) -> None:
        """Shut the inner bus down and close the log."""
        if self._is_shutdown:
            return
        super().shutdown()
        self.inner.shutdown()
        self.listener.stop()

    @property
    def protocol(self) -> Any:
        """The inner bus's CAN protocol."""
        return self.inner.protocol


__all__ = ["TappedBus"]

"""A bus tap: the controller's bus, with every frame it sends or receives handed to the bus log.

The controller owns its bus and reads it itself, so a ``can.Notifier`` would
steal its frames; this wrapper logs on the way through instead. Each logged
frame is a copy carrying its direction (sent: ``is_rx`` false, candump ``T``,
ASC ``Tx``; received: ``R``/``Rx``) and the one configured channel name, so a
session reads as one bus in SavvyCAN or CANalyzer. With a
:class:`~millctl.records.RecordQueue` the log is written on the records
thread: the control loop never waits for the disk (SAFETY 23). The log is
:class:`millctl.protocol.RotatingBusLog` (candump ``.log``, one file per session,
rotated by size).
"""

from __future__ import annotations

import copy
import logging
import time
from typing import Any

import can

from millctl.records import RecordQueue

log = logging.getLogger(__name__)


class TappedBus(can.BusABC):
    """Delegates to ``inner``; every frame sent or received also goes to ``listener`` (through ``records``)."""

    def __init__(
        self, inner: can.BusABC, listener: can.Listener, *, channel: str, records: RecordQueue | None = None
    ) -> None:
        self.inner = inner
        self.listener = listener
        self.log_channel = channel
        self.records = records
        self.channel_info = f"tapped {inner.channel_info}"
        super().__init__(channel=getattr(inner, "channel", "") or "")

    def _write(self, entry: can.Message) -> None:
        self.listener.on_message_received(entry)

    def _log(self, msg: can.Message, *, sent: bool) -> None:
        entry = copy.copy(msg)
        entry.is_rx = not sent
        entry.channel = self.log_channel
        if sent or not entry.timestamp:
            entry.timestamp = time.time()
        if self.records is not None:
            self.records.submit(lambda: self._write(entry))
            return
        try:
            self._write(entry)
        except Exception as exc:  # the bus log must never stop the control loop, whatever the frame holds
            log.error("bus log write failed: %s", exc)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send through the inner bus, then log the frame as sent (Tx), timestamped now."""
        self.inner.send(msg, timeout)
        self._log(msg, sent=True)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        msg = self.inner.recv(timeout)
        if msg is not None:
            self._log(msg, sent=False)
        return msg, True

    def shutdown(self) -> None:
        """Shut the inner bus down and close the log (after the frames still queued for it)."""
        if self._is_shutdown:
            return
        super().shutdown()
        self.inner.shutdown()
        if self.records is not None:
            self.records.submit(self.listener.stop)
        else:
            self.listener.stop()

    @property
    def protocol(self) -> Any:
        """The inner bus's CAN protocol."""
        return self.inner.protocol


__all__ = ["TappedBus"]

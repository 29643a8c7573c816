"""Errors of the protocol layer.

``ProtocolError`` is a :class:`~millctl.errors.BusError` (exit code 3): a frame
on the bus that does not fit the DBC is a bus problem, whoever sent it.
``SignalRangeError`` is an :class:`~millctl.errors.InvalidInputError` (exit
code 1): our own code asked to send a value the wire cannot carry.
"""

from __future__ import annotations

from millctl.errors import BusError, InvalidInputError


class ProtocolError(BusError):
    """A received frame does not fit ``config/millbus.dbc`` (unknown ID, length, value), or the DBC is unusable."""


class SignalRangeError(InvalidInputError):
    """A value to encode lies outside its signal's range in the DBC; names the signal, value and range."""

    def __init__(self, message: str, signal: str, value: object, minimum: float, maximum: float, unit: str) -> None:
        self.message_name = message
        self.signal = signal
        self.value = value
        self.minimum = minimum
        self.maximum = maximum
        self.unit = unit
        shown_unit = f" {unit}" if unit else ""
        super().__init__(
            f"{message}.{signal} = {value!r} is outside its range {minimum:g} … {maximum:g}{shown_unit} "
            "(config/millbus.dbc); refusing to encode"
        )


__all__ = ["ProtocolError", "SignalRangeError"]

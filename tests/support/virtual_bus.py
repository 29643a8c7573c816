"""python-can's ``virtual`` bus for the tests, with each receiver's copy made directly instead of by ``copy.deepcopy``.

python-can's :class:`~can.interfaces.virtual.VirtualBus` gives every receiver on the channel a copy of each
frame sent, made with ``copy.deepcopy``: the generic machinery (its memo, ``bytearray.__reduce_ex__``,
``copyreg``) costs more than the frame's encoding, and the unit tier's simulated mill sends a few hundred
thousand frames (the node, the controller and a bystander on one channel, 100 ticks a second of mill
time). This bus is python-can's, unchanged, but for what it copies: the frame is handed over as a
:class:`_Frame`, whose ``__deepcopy__`` builds the receiver's :class:`can.Message` field by field with its
own data buffer. Each receiver still gets its own message (its ``data`` independent of the sender's and of
every other receiver's); timestamps, ``channel``, ``is_rx``, own echo (``receive_own_messages``), queue
sizes, timeouts and errors are python-can's own, as are the receivers' message type.

``tests/conftest.py`` registers it as the ``virtual`` interface of every test process
(``can.interfaces.BACKENDS``), so the tests' own buses and the ones the product opens from a config alike
(``millctl.protocol.factory.open_bus``) are this one.
"""

from __future__ import annotations

from typing import Any

import can
from can.interfaces.virtual import VirtualBus as _PythonCanVirtualBus

_FIELDS = tuple(name for name in can.Message.__slots__ if name != "__weakref__")
"""The fields of a frame (``can.Message``'s slots but its weak-reference slot)."""

INTERFACE = "virtual"
BACKEND = (__name__, "VirtualBus")
"""This bus as an entry of ``can.interfaces.BACKENDS`` (module, class)."""


class _Frame(can.Message):
    """A frame on its way to the receivers: each gets a plain :class:`can.Message` of its own."""

    __slots__ = ()

    def __deepcopy__(self, memo: dict[int, Any] | None) -> can.Message:
        copy = can.Message.__new__(can.Message)
        for name in _FIELDS:
            setattr(copy, name, getattr(self, name))
        copy.data = bytearray() if self.is_remote_frame else bytearray(self.data)  # as can.Message() makes it
        return copy


class VirtualBus(_PythonCanVirtualBus):
    """python-can's virtual bus; what it copies for each receiver is made directly (see the module)."""

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send ``msg`` to every other bus on the channel (and back to this one with ``receive_own_messages``)."""
        frame = _Frame.__new__(_Frame)
        for name in _FIELDS:
            setattr(frame, name, getattr(msg, name))
        super().send(frame, timeout)


def install() -> None:
    """Make this bus python-can's ``virtual`` interface in this process."""
    can.interfaces.BACKENDS[INTERFACE] = BACKEND


class StatefulVirtualBus(VirtualBus):
    """A virtual bus whose driver reports the CAN controller's state, as ixxat's and etas's do (tests set it)."""

    bus_state = can.BusState.ACTIVE

    @property
    def state(self) -> can.BusState:
        return self.bus_state

    @state.setter
    def state(self, new_state: can.BusState) -> None:
        self.bus_state = new_state


__all__ = ["BACKEND", "INTERFACE", "StatefulVirtualBus", "VirtualBus", "install"]

"""The CiA 402 power state machine as data, driven from the control loop's tick without ever blocking.

Statusword masks name the state (CiA 402 §6.2, the table python-canopen's
``State402`` keeps too); :data:`NEXT_STEP` says, for the state a drive is in
and the state the controller wants, which controlword to send and which state
must follow. :class:`PowerMachine` sends that controlword on every RPDO,
judges the statusword that arrives by TPDO with its age, and reports a step the
drive did not take within its deadline (the caller escalates, as it does a
millbus command that is not confirmed: docs/safety.md#every-command-confirmed).
A fault reset is the rising edge of controlword bit 7; a quick stop is
confirmed by the state that the quick-stop option code 0x605A promises.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass


class Power(enum.StrEnum):
    """The CiA 402 power states (statusword 0x6041)."""

    NOT_READY_TO_SWITCH_ON = "NOT READY TO SWITCH ON"
    SWITCH_ON_DISABLED = "SWITCH ON DISABLED"
    READY_TO_SWITCH_ON = "READY TO SWITCH ON"
    SWITCHED_ON = "SWITCHED ON"
    OPERATION_ENABLED = "OPERATION ENABLED"
    QUICK_STOP_ACTIVE = "QUICK STOP ACTIVE"
    FAULT_REACTION_ACTIVE = "FAULT REACTION ACTIVE"
    FAULT = "FAULT"


P = Power

STATUSWORD_MASKS: tuple[tuple[int, int, Power], ...] = (
    (0x4F, 0x00, P.NOT_READY_TO_SWITCH_ON),
    (0x4F, 0x40, P.SWITCH_ON_DISABLED),
    (0x6F, 0x21, P.READY_TO_SWITCH_ON),
    (0x6F, 0x23, P.SWITCHED_ON),
    (0x6F, 0x27, P.OPERATION_ENABLED),
    (0x6F, 0x07, P.QUICK_STOP_ACTIVE),
    (0x4F, 0x0F, P.FAULT_REACTION_ACTIVE),
    (0x4F, 0x08, P.FAULT),
)
"""(mask, value, state): a statusword ``sw`` is in ``state`` when ``sw & mask == value``."""


class Controlword(enum.IntEnum):
    """The device-control commands (controlword 0x6040, bits 0–3 and 7)."""

    DISABLE_VOLTAGE = 0x00
    QUICK_STOP = 0x02
    SHUTDOWN = 0x06
    SWITCH_ON = 0x07
    """Also DISABLE OPERATION from OPERATION ENABLED."""
    ENABLE_OPERATION = 0x0F
    FAULT_RESET = 0x80
    """Acts on the rising edge of bit 7."""


C = Controlword

NEXT_STEP: dict[tuple[Power, Power], tuple[Controlword, Power]] = {
    # towards OPERATION ENABLED (arm)
    (P.SWITCH_ON_DISABLED, P.OPERATION_ENABLED): (C.SHUTDOWN, P.READY_TO_SWITCH_ON),
    (P.READY_TO_SWITCH_ON, P.OPERATION_ENABLED): (C.SWITCH_ON, P.SWITCHED_ON),
    (P.SWITCHED_ON, P.OPERATION_ENABLED): (C.ENABLE_OPERATION, P.OPERATION_ENABLED),
    (P.OPERATION_ENABLED, P.OPERATION_ENABLED): (C.ENABLE_OPERATION, P.OPERATION_ENABLED),
    (P.QUICK_STOP_ACTIVE, P.OPERATION_ENABLED): (C.DISABLE_VOLTAGE, P.SWITCH_ON_DISABLED),
    # towards SWITCH ON DISABLED (disarm, reset)
    (P.SWITCH_ON_DISABLED, P.SWITCH_ON_DISABLED): (C.DISABLE_VOLTAGE, P.SWITCH_ON_DISABLED),
    (P.READY_TO_SWITCH_ON, P.SWITCH_ON_DISABLED): (C.DISABLE_VOLTAGE, P.SWITCH_ON_DISABLED),
    (P.SWITCHED_ON, P.SWITCH_ON_DISABLED): (C.DISABLE_VOLTAGE, P.SWITCH_ON_DISABLED),
    (P.OPERATION_ENABLED, P.SWITCH_ON_DISABLED): (C.DISABLE_VOLTAGE, P.SWITCH_ON_DISABLED),
    (P.QUICK_STOP_ACTIVE, P.SWITCH_ON_DISABLED): (C.DISABLE_VOLTAGE, P.SWITCH_ON_DISABLED),
    (P.FAULT, P.SWITCH_ON_DISABLED): (C.FAULT_RESET, P.SWITCH_ON_DISABLED),
    # towards QUICK STOP ACTIVE (E-stop): from a disabled state a quick stop lands in SWITCH ON DISABLED
    (P.OPERATION_ENABLED, P.QUICK_STOP_ACTIVE): (C.QUICK_STOP, P.QUICK_STOP_ACTIVE),
    (P.QUICK_STOP_ACTIVE, P.QUICK_STOP_ACTIVE): (C.QUICK_STOP, P.QUICK_STOP_ACTIVE),
    (P.SWITCHED_ON, P.QUICK_STOP_ACTIVE): (C.QUICK_STOP, P.SWITCH_ON_DISABLED),
    (P.READY_TO_SWITCH_ON, P.QUICK_STOP_ACTIVE): (C.QUICK_STOP, P.SWITCH_ON_DISABLED),
    (P.SWITCH_ON_DISABLED, P.QUICK_STOP_ACTIVE): (C.QUICK_STOP, P.SWITCH_ON_DISABLED),
}
"""(state now, state wanted) → (controlword to send, state that must follow). Missing: wait (the drive acts alone)."""

QUICK_STOP_ENDS_IN: dict[int, Power] = {
    **{code: P.SWITCH_ON_DISABLED for code in (0, 1, 2, 3, 4)},
    **{code: P.QUICK_STOP_ACTIVE for code in (5, 6, 7, 8)},
}
"""The state a quick stop promises by its option code 0x605A (0: disable drive function at once)."""

QUICK_STOP_OPTION = 6
"""The 0x605A millctl writes: slow down on the quick-stop ramp and stay in QUICK STOP ACTIVE."""


def decode_statusword(statusword: int) -> Power:
    """The power state a statusword shows (CiA 402 §6.2)."""
    for mask, value, state in STATUSWORD_MASKS:
        if statusword & mask == value:
            return state
    return P.NOT_READY_TO_SWITCH_ON


def quick_stop_shown(state: Power) -> bool:
    """True when a statusword shows a quick stop taken (or a drive already off or faulted)."""
    return state in (P.QUICK_STOP_ACTIVE, P.SWITCH_ON_DISABLED, P.FAULT_REACTION_ACTIVE, P.FAULT)


def quick_stop_complete(state: Power, option_code: int, at_standstill: bool) -> bool:
    """True when a quick stop is done: the state 0x605A promises, at standstill (not only QUICK STOP ACTIVE)."""
    promised = QUICK_STOP_ENDS_IN.get(option_code, P.QUICK_STOP_ACTIVE)
    return at_standstill and state in (promised, P.SWITCH_ON_DISABLED)


@dataclass
class PowerMachine:
    """One drive's power state, driven towards ``wanted`` from the tick (times in s, controller clock)."""

    confirm_s: float
    """A step not taken within this bound is stuck (``interlock.command_confirm_s``)."""
    stale_s: float
    """A statusword older than this is not believed (the drive's state is unknown)."""
    wanted: Power = P.SWITCH_ON_DISABLED
    state: Power | None = None
    statusword: int | None = None
    received_s: float = float("-inf")
    _step_from: Power | None = None
    _step_since_s: float = 0.0
    _reset_edge: bool = False

    def observe(self, statusword: int, now_s: float) -> Power:
        """A statusword from the drive's TPDO (its age starts now)."""
        state = decode_statusword(statusword)
        if state != self.state:
            self._step_from, self._step_since_s = state, now_s
        self.state, self.statusword, self.received_s = state, statusword, now_s
        return state

    def want(self, wanted: Power, now_s: float) -> None:
        """Head for ``wanted`` (OPERATION ENABLED, SWITCH ON DISABLED or QUICK STOP ACTIVE); the deadline starts."""
        if wanted != self.wanted:
            self.wanted = wanted
            self._step_since_s = now_s

    def believed(self, now_s: float) -> Power | None:
        """The state the statusword shows, or None when it is older than its bound."""
        return self.state if now_s - self.received_s <= self.stale_s else None

    def controlword(self, now_s: float) -> int:
        """What to send now: the table's step from the believed state (a fault reset as an edge)."""
        state = self.believed(now_s)
        if state is None:
            return int(C.QUICK_STOP if self.wanted is P.QUICK_STOP_ACTIVE else C.DISABLE_VOLTAGE)
        step = NEXT_STEP.get((state, self.wanted))
        if step is None:  # FAULT without a reset wanted, or a drive acting alone: hold it disabled
            return int(C.QUICK_STOP if self.wanted is P.QUICK_STOP_ACTIVE else C.DISABLE_VOLTAGE)
        word = step[0]
        if word is C.FAULT_RESET:
            self._reset_edge = not self._reset_edge  # 0x00, 0x80, 0x00, …: a rising edge every other send
            return int(C.FAULT_RESET if self._reset_edge else C.DISABLE_VOLTAGE)
        return int(word)

    def stuck(self, now_s: float) -> str | None:
        """Why the drive has not taken its next step within the deadline (None while on time or there)."""
        state = self.believed(now_s)
        if state is None:
            return None  # the caller judges a stale statusword as stale telemetry
        if state is self.wanted or (self.wanted is P.QUICK_STOP_ACTIVE and quick_stop_shown(state)):
            return None
        step = NEXT_STEP.get((state, self.wanted))
        if step is None or now_s - self._step_since_s <= self.confirm_s:
            return None
        word, follows = step
        shown = f"0x{self.statusword:04X}" if self.statusword is not None else "none"
        return (
            f"{state} → {follows} (controlword 0x{int(word):02X}, towards {self.wanted}) not confirmed by the "
            f"statusword within {self.confirm_s:.2f} s (statusword {shown}; interlock.command_confirm_s)"
        )


__all__ = [
    "NEXT_STEP",
    "QUICK_STOP_ENDS_IN",
    "QUICK_STOP_OPTION",
    "STATUSWORD_MASKS",
    "Controlword",
    "Power",
    "PowerMachine",
    "decode_statusword",
    "quick_stop_complete",
    "quick_stop_shown",
]

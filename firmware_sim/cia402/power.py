"""The drive side of the CiA 402 power state machine, as data: controlword commands, transitions, statuswords.

A drive decodes each controlword into one of the device-control commands
(CiA 402 part 2, table "device control commands") and looks the transition
up in :data:`TRANSITIONS` (the numbered transitions of the standard's state
diagram); commands a state does not accept change nothing. The automatic
transitions (0/1 after power-up, 12 at the end of a quick stop, 14 at the
end of the fault reaction) and the fault (13) are the drive's own, in
:mod:`firmware_sim.cia402.drive`. The statusword of each state is
:func:`statusword`; the masks are the standard's (``xxxx xxxx x0xx 0000`` …),
the same the controller judges.
"""

from __future__ import annotations

import enum


class PowerState(enum.Enum):
    """The CiA 402 power states of a drive."""

    NOT_READY_TO_SWITCH_ON = "NOT READY TO SWITCH ON"
    SWITCH_ON_DISABLED = "SWITCH ON DISABLED"
    READY_TO_SWITCH_ON = "READY TO SWITCH ON"
    SWITCHED_ON = "SWITCHED ON"
    OPERATION_ENABLED = "OPERATION ENABLED"
    QUICK_STOP_ACTIVE = "QUICK STOP ACTIVE"
    FAULT_REACTION_ACTIVE = "FAULT REACTION ACTIVE"
    FAULT = "FAULT"


class Command(enum.Enum):
    """The device-control commands a controlword encodes (bits 0–3 and 7)."""

    SHUTDOWN = "shutdown"
    SWITCH_ON = "switch on"
    ENABLE_OPERATION = "enable operation"
    DISABLE_VOLTAGE = "disable voltage"
    QUICK_STOP = "quick stop"
    FAULT_RESET = "fault reset"
    NONE = "none"


CW_SWITCH_ON = 1 << 0
CW_ENABLE_VOLTAGE = 1 << 1
CW_QUICK_STOP = 1 << 2
"""Controlword bit 2: 0 commands a quick stop (active low)."""
CW_ENABLE_OPERATION = 1 << 3
CW_FAULT_RESET = 1 << 7
"""Controlword bit 7: its rising edge resets a fault."""
CW_HALT = 1 << 8
"""Controlword bit 8: the profile decelerates to rest and holds while set."""

SW_READY_TO_SWITCH_ON = 1 << 0
SW_SWITCHED_ON = 1 << 1
SW_OPERATION_ENABLED = 1 << 2
SW_FAULT = 1 << 3
SW_VOLTAGE_ENABLED = 1 << 4
SW_QUICK_STOP = 1 << 5
"""Statusword bit 5: 1 while *no* quick stop is active (active low)."""
SW_SWITCH_ON_DISABLED = 1 << 6
SW_WARNING = 1 << 7
SW_REMOTE = 1 << 9
SW_TARGET_REACHED = 1 << 10
SW_INTERNAL_LIMIT = 1 << 11
"""Statusword bit 11: the target was limited (0x607F/0x6080)."""
SW_SPEED_ZERO = 1 << 12
"""Statusword bit 12 in profile velocity mode: the velocity actual value is (about) zero."""

STATE_BITS: dict[PowerState, int] = {
    PowerState.NOT_READY_TO_SWITCH_ON: 0x0000,
    PowerState.SWITCH_ON_DISABLED: 0x0040,
    PowerState.READY_TO_SWITCH_ON: 0x0021,
    PowerState.SWITCHED_ON: 0x0023,
    PowerState.OPERATION_ENABLED: 0x0027,
    PowerState.QUICK_STOP_ACTIVE: 0x0007,
    PowerState.FAULT_REACTION_ACTIVE: 0x000F,
    PowerState.FAULT: 0x0008,
}
"""The state bits (0–3, 5, 6) of each state's statusword."""

STATE_MASKS: dict[PowerState, int] = {
    PowerState.NOT_READY_TO_SWITCH_ON: 0x4F,
    PowerState.SWITCH_ON_DISABLED: 0x4F,
    PowerState.READY_TO_SWITCH_ON: 0x6F,
    PowerState.SWITCHED_ON: 0x6F,
    PowerState.OPERATION_ENABLED: 0x6F,
    PowerState.QUICK_STOP_ACTIVE: 0x6F,
    PowerState.FAULT_REACTION_ACTIVE: 0x4F,
    PowerState.FAULT: 0x4F,
}
"""The statusword mask that identifies each state (CiA 402)."""

POWERED = frozenset({PowerState.OPERATION_ENABLED, PowerState.QUICK_STOP_ACTIVE, PowerState.FAULT_REACTION_ACTIVE})
"""States in which the drive applies torque (the motor follows the drive's profile); elsewhere it coasts."""

_S = PowerState
TRANSITIONS: dict[tuple[PowerState, Command], PowerState] = {
    (_S.SWITCH_ON_DISABLED, Command.SHUTDOWN): _S.READY_TO_SWITCH_ON,  # 2
    (_S.READY_TO_SWITCH_ON, Command.SWITCH_ON): _S.SWITCHED_ON,  # 3
    (_S.READY_TO_SWITCH_ON, Command.ENABLE_OPERATION): _S.SWITCHED_ON,  # 3 (then 4 on the next controlword)
    (_S.SWITCHED_ON, Command.ENABLE_OPERATION): _S.OPERATION_ENABLED,  # 4
    (_S.OPERATION_ENABLED, Command.SWITCH_ON): _S.SWITCHED_ON,  # 5 (disable operation)
    (_S.SWITCHED_ON, Command.SHUTDOWN): _S.READY_TO_SWITCH_ON,  # 6
    (_S.READY_TO_SWITCH_ON, Command.DISABLE_VOLTAGE): _S.SWITCH_ON_DISABLED,  # 7
    (_S.READY_TO_SWITCH_ON, Command.QUICK_STOP): _S.SWITCH_ON_DISABLED,  # 7
    (_S.OPERATION_ENABLED, Command.SHUTDOWN): _S.READY_TO_SWITCH_ON,  # 8
    (_S.OPERATION_ENABLED, Command.DISABLE_VOLTAGE): _S.SWITCH_ON_DISABLED,  # 9
    (_S.SWITCHED_ON, Command.DISABLE_VOLTAGE): _S.SWITCH_ON_DISABLED,  # 10
    (_S.SWITCHED_ON, Command.QUICK_STOP): _S.SWITCH_ON_DISABLED,  # 10
    (_S.OPERATION_ENABLED, Command.QUICK_STOP): _S.QUICK_STOP_ACTIVE,  # 11
    (_S.QUICK_STOP_ACTIVE, Command.DISABLE_VOLTAGE): _S.SWITCH_ON_DISABLED,  # 12
    (_S.FAULT, Command.FAULT_RESET): _S.SWITCH_ON_DISABLED,  # 15 (only with the cause gone: the drive checks)
}
"""(state, command) → next state; a pair not in the table leaves the state as it is.

QUICK STOP ACTIVE → OPERATION ENABLED (16) is left out: 0x605A = 5–8 would allow it, and this drive
offers only the codes that end a quick stop in SWITCH ON DISABLED or hold it (docs/protocol.md, "CiA 402").
"""


def decode(controlword: int, previous: int) -> Command:
    """The command a controlword gives, ``previous`` being the one before it (bit 7's rising edge is a reset)."""
    if controlword & CW_FAULT_RESET and not previous & CW_FAULT_RESET:
        return Command.FAULT_RESET
    if controlword & CW_FAULT_RESET:
        return Command.NONE  # bit 7 held high: the reset happened at its edge
    low = controlword & 0x0F
    if not low & CW_ENABLE_VOLTAGE:
        return Command.DISABLE_VOLTAGE
    if not low & CW_QUICK_STOP:
        return Command.QUICK_STOP
    if low & 0x07 == 0x06:
        return Command.SHUTDOWN
    if low == 0x07:
        return Command.SWITCH_ON
    if low == 0x0F:
        return Command.ENABLE_OPERATION
    return Command.NONE


def next_state(state: PowerState, command: Command) -> PowerState:
    """The state after ``command`` in ``state`` (unchanged when the state does not accept it)."""
    return TRANSITIONS.get((state, command), state)


def statusword(state: PowerState, *, extra: int = 0) -> int:
    """The statusword of ``state`` (voltage enabled while switched on or beyond, remote always) plus ``extra`` bits."""
    word = STATE_BITS[state] | SW_REMOTE | extra
    if state in POWERED or state in (PowerState.READY_TO_SWITCH_ON, PowerState.SWITCHED_ON):
        word |= SW_VOLTAGE_ENABLED
    return word & 0xFFFF


def state_of(word: int) -> PowerState | None:
    """The state a statusword shows (None when it matches no state's mask)."""
    for state, mask in STATE_MASKS.items():
        if word & mask == STATE_BITS[state]:
            return state
    return None


__all__ = [
    "CW_ENABLE_OPERATION",
    "CW_ENABLE_VOLTAGE",
    "CW_FAULT_RESET",
    "CW_HALT",
    "CW_QUICK_STOP",
    "CW_SWITCH_ON",
    "POWERED",
    "STATE_BITS",
    "STATE_MASKS",
    "SW_FAULT",
    "SW_INTERNAL_LIMIT",
    "SW_QUICK_STOP",
    "SW_REMOTE",
    "SW_SPEED_ZERO",
    "SW_SWITCH_ON_DISABLED",
    "SW_TARGET_REACHED",
    "SW_VOLTAGE_ENABLED",
    "SW_WARNING",
    "TRANSITIONS",
    "Command",
    "PowerState",
    "decode",
    "next_state",
    "state_of",
    "statusword",
]

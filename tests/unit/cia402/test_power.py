"""The drive-side CiA 402 power state machine (firmware_sim/cia402/power.py): the standard's commands and states."""

from __future__ import annotations

import pytest

from firmware_sim.cia402.power import Command, PowerState, decode, next_state, state_of, statusword

S = PowerState


@pytest.mark.parametrize(
    ("controlword", "command"),
    [
        (0x0006, Command.SHUTDOWN),  # 0xxx x110
        (0x000E, Command.SHUTDOWN),
        (0x0007, Command.SWITCH_ON),  # 0xxx 0111
        (0x000F, Command.ENABLE_OPERATION),  # 0xxx 1111
        (0x0000, Command.DISABLE_VOLTAGE),  # 0xxx xx0x
        (0x000D, Command.DISABLE_VOLTAGE),
        (0x0002, Command.QUICK_STOP),  # 0xxx x01x
        (0x000B, Command.QUICK_STOP),
        (0x010F, Command.ENABLE_OPERATION),  # halt (bit 8) is not a device-control command
    ],
)
def test_each_controlword_decodes_to_its_device_control_command(controlword: int, command: Command) -> None:
    assert decode(controlword, previous=0) is command


def test_fault_reset_is_the_rising_edge_of_bit_7() -> None:
    assert decode(0x0080, previous=0x0000) is Command.FAULT_RESET
    assert decode(0x0080, previous=0x0080) is Command.NONE  # held high: no second reset


@pytest.mark.parametrize(
    ("state", "command", "after"),
    [
        (S.SWITCH_ON_DISABLED, Command.SHUTDOWN, S.READY_TO_SWITCH_ON),  # 2
        (S.READY_TO_SWITCH_ON, Command.SWITCH_ON, S.SWITCHED_ON),  # 3
        (S.SWITCHED_ON, Command.ENABLE_OPERATION, S.OPERATION_ENABLED),  # 4
        (S.OPERATION_ENABLED, Command.SWITCH_ON, S.SWITCHED_ON),  # 5
        (S.SWITCHED_ON, Command.SHUTDOWN, S.READY_TO_SWITCH_ON),  # 6
        (S.READY_TO_SWITCH_ON, Command.DISABLE_VOLTAGE, S.SWITCH_ON_DISABLED),  # 7
        (S.OPERATION_ENABLED, Command.SHUTDOWN, S.READY_TO_SWITCH_ON),  # 8
        (S.OPERATION_ENABLED, Command.DISABLE_VOLTAGE, S.SWITCH_ON_DISABLED),  # 9
        (S.SWITCHED_ON, Command.QUICK_STOP, S.SWITCH_ON_DISABLED),  # 10
        (S.OPERATION_ENABLED, Command.QUICK_STOP, S.QUICK_STOP_ACTIVE),  # 11
        (S.QUICK_STOP_ACTIVE, Command.DISABLE_VOLTAGE, S.SWITCH_ON_DISABLED),  # 12
        (S.FAULT, Command.FAULT_RESET, S.SWITCH_ON_DISABLED),  # 15
        # commands a state does not accept change nothing
        (S.SWITCH_ON_DISABLED, Command.ENABLE_OPERATION, S.SWITCH_ON_DISABLED),
        (S.FAULT, Command.ENABLE_OPERATION, S.FAULT),
        (S.QUICK_STOP_ACTIVE, Command.ENABLE_OPERATION, S.QUICK_STOP_ACTIVE),
        (S.FAULT_REACTION_ACTIVE, Command.FAULT_RESET, S.FAULT_REACTION_ACTIVE),
    ],
)
def test_transitions_follow_the_standards_diagram(state: PowerState, command: Command, after: PowerState) -> None:
    assert next_state(state, command) is after


@pytest.mark.parametrize("state", list(PowerState))
def test_each_states_statusword_shows_that_state(state: PowerState) -> None:
    word = statusword(state, extra=0x1C00)  # target reached, internal limit, speed zero: not state bits
    assert state_of(word) is state
    assert word & 0x0200  # remote
    assert bool(word & 0x0010) is (state not in (S.NOT_READY_TO_SWITCH_ON, S.SWITCH_ON_DISABLED, S.FAULT))

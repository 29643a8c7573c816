"""The CiA 402 power state machine as tables: statusword decoding, the path to each wanted state, deadlines."""

from __future__ import annotations

import pytest

from millctl.drives.cia402.state402 import (
    NEXT_STEP,
    Controlword,
    Power,
    PowerMachine,
    decode_statusword,
    quick_stop_complete,
    quick_stop_shown,
)

P = Power


@pytest.mark.parametrize(
    ("statusword", "state"),
    [
        (0x0000, P.NOT_READY_TO_SWITCH_ON),
        (0x0250, P.SWITCH_ON_DISABLED),
        (0x0231, P.READY_TO_SWITCH_ON),
        (0x0233, P.SWITCHED_ON),
        (0x0237, P.OPERATION_ENABLED),
        (0x0217, P.QUICK_STOP_ACTIVE),
        (0x021F, P.FAULT_REACTION_ACTIVE),
        (0x0218, P.FAULT),
        (0x0638, P.FAULT),  # warning and target-reached bits do not change the state
    ],
)
def test_each_statusword_names_its_power_state(statusword: int, state: Power) -> None:
    assert decode_statusword(statusword) is state


STATUSWORD_OF = {P.SWITCH_ON_DISABLED: 0x0250, P.READY_TO_SWITCH_ON: 0x0231, P.SWITCHED_ON: 0x0233,
                 P.OPERATION_ENABLED: 0x0237, P.QUICK_STOP_ACTIVE: 0x0217, P.FAULT: 0x0218}


def _walk(start: Power, wanted: Power) -> list[int]:
    """Follow the table from ``start`` to ``wanted`` as an obedient drive would; the controlwords sent."""
    machine = PowerMachine(confirm_s=0.5, stale_s=0.2)
    machine.observe(STATUSWORD_OF[start], 0.0)
    machine.want(wanted, 0.0)
    words, state = [], start
    for _ in range(6):
        word = machine.controlword(0.0)
        words.append(word)
        step = NEXT_STEP[(state, wanted)]
        if step[1] is state:
            return words
        state = step[1]
        machine.observe(STATUSWORD_OF[state], 0.0)
    raise AssertionError(f"no path from {start} to {wanted}: {words}")


def test_arming_goes_shutdown_switch_on_enable_operation() -> None:
    assert _walk(P.SWITCH_ON_DISABLED, P.OPERATION_ENABLED) == [0x06, 0x07, 0x0F, 0x0F]


def test_disarming_from_operation_enabled_is_disable_voltage() -> None:
    assert _walk(P.OPERATION_ENABLED, P.SWITCH_ON_DISABLED) == [0x00, 0x00]


def test_a_quick_stop_from_operation_enabled_holds_quick_stop() -> None:
    assert _walk(P.OPERATION_ENABLED, P.QUICK_STOP_ACTIVE) == [0x02, 0x02]


def test_a_fault_reset_is_a_rising_edge_of_bit_7_repeated_until_the_drive_leaves_fault() -> None:
    machine = PowerMachine(confirm_s=0.5, stale_s=0.2)
    machine.observe(STATUSWORD_OF[P.FAULT], 0.0)
    machine.want(P.SWITCH_ON_DISABLED, 0.0)
    words = [machine.controlword(0.0) for _ in range(4)]
    assert words == [Controlword.FAULT_RESET, 0x00, Controlword.FAULT_RESET, 0x00]


def test_a_fault_without_a_reset_wanted_is_held_disabled_not_reset() -> None:
    machine = PowerMachine(confirm_s=0.5, stale_s=0.2)
    machine.observe(STATUSWORD_OF[P.FAULT], 0.0)
    machine.want(P.OPERATION_ENABLED, 0.0)
    assert {machine.controlword(0.0) for _ in range(3)} == {0x00}


def test_a_step_not_confirmed_within_its_deadline_is_stuck_naming_the_transition() -> None:
    machine = PowerMachine(confirm_s=0.5, stale_s=10.0)
    machine.observe(STATUSWORD_OF[P.SWITCH_ON_DISABLED], 0.0)
    machine.want(P.OPERATION_ENABLED, 0.0)
    assert machine.stuck(0.4) is None
    machine.observe(STATUSWORD_OF[P.SWITCH_ON_DISABLED], 0.45)  # the drive answers, but does not move
    reason = machine.stuck(0.6)
    assert reason is not None
    assert "SWITCH ON DISABLED → READY TO SWITCH ON" in reason and "0x06" in reason and "0x0250" in reason


def test_each_step_taken_restarts_the_deadline() -> None:
    machine = PowerMachine(confirm_s=0.5, stale_s=10.0)
    machine.observe(STATUSWORD_OF[P.SWITCH_ON_DISABLED], 0.0)
    machine.want(P.OPERATION_ENABLED, 0.0)
    machine.observe(STATUSWORD_OF[P.READY_TO_SWITCH_ON], 0.4)
    assert machine.stuck(0.8) is None
    assert machine.stuck(1.0) is not None


def test_a_stale_statusword_is_not_believed() -> None:
    machine = PowerMachine(confirm_s=0.5, stale_s=0.2)
    machine.observe(STATUSWORD_OF[P.OPERATION_ENABLED], 0.0)
    assert machine.believed(0.1) is P.OPERATION_ENABLED
    assert machine.believed(0.3) is None
    machine.want(P.OPERATION_ENABLED, 0.3)
    assert machine.controlword(0.3) == Controlword.DISABLE_VOLTAGE  # never enable on a state it cannot see


@pytest.mark.parametrize(("option", "promised"), [(2, P.SWITCH_ON_DISABLED), (6, P.QUICK_STOP_ACTIVE)])
def test_a_quick_stop_is_complete_in_the_state_its_option_code_promises_at_standstill(
    option: int, promised: Power
) -> None:
    assert quick_stop_complete(promised, option, at_standstill=True)
    assert not quick_stop_complete(promised, option, at_standstill=False)
    assert not quick_stop_complete(P.OPERATION_ENABLED, option, at_standstill=True)
    assert quick_stop_shown(P.SWITCH_ON_DISABLED)  # QUICK STOP ACTIVE may pass straight on (0x605A 1–4)

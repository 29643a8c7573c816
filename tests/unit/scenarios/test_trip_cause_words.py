"""A node fault's trip cause names the fault bits as an operator reads them, not as Python prints an enum.

Issue 39, item 8: the cause read "node fault STALL (fault bits <FaultFlag.STALL: 32>)".
"""

from __future__ import annotations

from millctl.controller import ControllerState
from millctl.protocol import SimFaultCode
from millctl.protocol.messages import FaultFlag
from tests.unit.scenarios.rig import Rig


def test_a_vibration_stall_trips_with_the_fault_bits_by_name(rig: Rig) -> None:
    rig.start(60.0, 400.0)
    rig.inject(SimFaultCode.VIB_STALL)
    rig.run(10.0, until=lambda: rig.controller.state is ControllerState.TRIPPED)
    cause = rig.controller.trip_cause
    assert rig.controller.state is ControllerState.TRIPPED, cause
    assert "fault bits STALL" in cause and "<" not in cause and "FaultFlag" not in cause, cause


def test_fault_bits_read_as_names() -> None:
    assert repr(FaultFlag.WATCHDOG | FaultFlag.ESTOP) == "WATCHDOG|ESTOP"
    assert repr(FaultFlag(0)) == "none"

"""An operator drill through ``millctl serve --fault-injection``: the instructor injects, the operator sees the trip."""

from __future__ import annotations

from millctl.api import ControllerState, EventKind, SimFaultName
from tests.support.service import private_dir, start_service, wait_for, write_config


def test_an_injected_vibration_stall_trips_and_is_recorded_as_a_drill() -> None:
    with private_dir() as directory:
        config = write_config(directory)
        service = start_service(directory, module_args=["millctl", "--config", str(config), "serve",
                                                        "--fault-injection"])
        try:
            assert "FAULT INJECTION on" in service.output()
            with service.client("operator") as operator, service.client("instructor") as instructor:
                assert operator.service().fault_injection
                with operator.control():  # the instructor needs no lease: the operator holds it
                    operator.arm()
                    operator.set_speeds(60.0, 300.0)
                    wait_for(lambda: (operator.status().measured_vibration_rpm or 0.0) > 100.0, 30.0, "ω_v moving")
                    assert instructor.inject_fault(SimFaultName.VIB_STALL).active == {}
                    wait_for(lambda: operator.status().state is ControllerState.TRIPPED, 30.0, "the stall's trip")
                    assert SimFaultName.VIB_STALL in instructor.faults().active
                    assert "STALL" in operator.status().node_faults
                    instructor.inject_fault(SimFaultName.CLEAR)
                    wait_for(lambda: instructor.faults().active == {}, 10.0, "the fault cleared")
                drills = [e for e in operator.events().events if e.kind is EventKind.DRILL]
                assert [e.data["fault"] for e in drills] == ["VIB_STALL", "CLEAR"]
                assert all(e.source.startswith("api:instructor@") for e in drills)
                assert drills[0].message == "fault drill: injected VIB_STALL (param 0)"
        finally:
            assert service.stop() == 0

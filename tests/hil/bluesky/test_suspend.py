"""A trip injected mid-plan (``serve --fault-injection``) suspends the plan; it resumes after reset and arm."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
from bluesky.run_engine import RunEngineResult

from millctl.api import ControllerState, EventKind, EventOut, SimFaultName
from millctl.bluesky import SuspendWhenMillNotReady
from millctl.bluesky.plans import mill_at
from millctl.client import ServiceRefused
from tests.hil.bluesky.conftest import Engine
from tests.support.service import Service, private_dir, start_service, wait_for, write_config

pytestmark = pytest.mark.timeout(600)  # a safety net: two spin-ups to 150/800 and a trip, on a loaded machine


@pytest.fixture
def drill_service() -> Iterator[Service]:
    """A service whose embedded node takes injected faults."""
    with private_dir() as directory:
        config = write_config(directory)
        running = start_service(directory, module_args=["millctl", "--config", str(config), "serve",
                                                        "--fault-injection"])
        try:
            yield running
        finally:
            running.stop()


def _operator(service: Service, engine: Engine, failures: list[BaseException]) -> None:
    """The instructor stalls the vibration drive mid-hold; the operator clears it, resets and arms."""
    try:
        with service.client("instructor") as instructor, service.client("operator") as operator:
            wait_for(lambda: len(engine.of("event", "primary")) >= 3, 180.0, "three readings at 150/800")
            instructor.inject_fault(SimFaultName.VIB_STALL)
            wait_for(lambda: operator.status().state is ControllerState.TRIPPED, 60.0, "the stall's trip")
            instructor.inject_fault(SimFaultName.CLEAR)
            wait_for(lambda: not operator.control_state().held, 60.0, "the plan giving control back")

            def reset_and_arm() -> bool:
                """As an operator does: reset once the drives are still (a refusal: try again), then arm."""
                try:
                    with operator.control():
                        if operator.status().state is ControllerState.TRIPPED:
                            operator.reset()
                        wait_for(lambda: operator.status().state is ControllerState.DISABLED, 30.0, "the reset")
                        operator.arm()
                except ServiceRefused:  # not at standstill yet (sensor noise counts), or control not free yet
                    return False
                return True

            wait_for(reset_and_arm, 180.0, "the operator's reset and arm")
    except BaseException as exc:  # seen by the test after the plan
        failures.append(exc)


def test_a_trip_mid_plan_suspends_it_and_it_resumes_after_reset_and_arm(drill_service: Service,
                                                                        engine: Engine) -> None:
    mill = engine.connect(drill_service.socket)
    engine.RE.record_interruptions = True
    engine.RE.install_suspender(SuspendWhenMillNotReady(mill))
    failures: list[BaseException] = []
    operator = threading.Thread(target=_operator, args=(drill_service, engine, failures), daemon=True)
    operator.start()
    started = time.monotonic()
    result = engine.RE(mill_at(mill, 150.0, 800.0, duration_s=10.0, period_s=1.0))
    operator.join(timeout=60.0)
    assert not failures, failures
    assert isinstance(result, RunEngineResult)
    assert result.exit_status == "success", result
    (interruption,) = engine.of("event", "interruptions")  # bluesky records the suspension, with its reason
    assert "TRIPPED" in interruption["data"]["interruption"]
    suspended = interruption["time"]
    primary = engine.of("event", "primary")
    def at_point(event: dict[str, Any]) -> bool:
        data = event["data"]
        return bool(data["mill-state"] == "RUNNING" and abs(data["mill-rotary"] - 150.0) <= 5.0)

    before = [e for e in primary if e["time"] < suspended]
    after = [e for e in primary if e["time"] > suspended and at_point(e)]
    assert len(before) >= 3 and all(at_point(e) for e in before[:3])
    assert after and at_point(primary[-1])  # back at the point after the resume, to the end
    # the hold was completed after the resume: time at the point on both sides adds up to the 10 s
    held = [e for e in before if at_point(e)]
    held_s = (held[-1]["time"] - held[0]["time"]) + (after[-1]["time"] - after[0]["time"])
    assert held_s >= 10.0 - 1.0 - 1e-6, held_s  # at most one reading period lost to the trip
    assert time.monotonic() - started > 10.0
    with drill_service.client("watch") as watch:
        events: list[EventOut] = []  # every page: under load there may be more than one page's 500
        while page := watch.events(after=events[-1].seq if events else 0, limit=2000).events:
            events += page
        assert not watch.control_state().held
    trips = [e for e in events if e.kind is EventKind.TRIP]
    assert trips
    operator_commands = [e.message.lower() for e in events
                         if e.kind is EventKind.COMMAND and e.source.startswith("api:operator@")]
    assert any("reset" in m for m in operator_commands) and any("arm" in m for m in operator_commands)

"""The furnace on the node (SAFETY.md item 11): refresh timeout, heating rate, verification, over-temperature."""

from __future__ import annotations

from collections.abc import Callable

from millctl.config import MillConfig
from millctl.protocol import FaultCode, FaultFlag, NodeState, Setpoints, SimFaultCode

from .conftest import Bench


def test_safety_11_heater_turns_off_when_its_setpoint_is_not_refreshed(bench: Bench) -> None:
    bench.arm()
    bench.setpoints(0.0, 0.0, 200.0, True)
    bench.step(0.1)
    assert bench.node.heater_on
    refresh_s = bench.config.furnace.setpoint_refresh_s
    bench.step(refresh_s - 0.3, dt_s=0.05)
    assert bench.node.heater_on
    bench.step(0.5, dt_s=0.05)
    assert not bench.node.heater_on
    assert bench.node.first_fault is FaultCode.HEATER_TIMEOUT
    assert bench.node.state is NodeState.FAULT


def test_safety_11_heating_rate_is_limited_and_the_loop_heats(bench: Bench) -> None:
    bench.arm()
    bench.hold = Setpoints(0.0, 0.0, 300.0, True)
    bench.step(0.1)
    start_c = bench.node.furnace_temp_c
    bench.step(60.0, dt_s=0.2)
    rise_c = bench.node.furnace_temp_c - start_c
    max_rate = bench.config.furnace.max_heating_rate_c_per_min
    assert 0.5 * max_rate < rise_c <= max_rate + 0.5
    assert bench.node.fault_bits == 0 and bench.node.heater_on


def test_safety_11_heater_verification_trips_when_heating_does_not_raise_the_temperature(
    config: MillConfig, make_bench: Callable[..., Bench]
) -> None:
    quick = config.model_copy(update={"furnace": config.furnace.model_copy(update={"verify_period_s": 5.0})})
    bench = make_bench(quick, fault_injection=True)
    bench.arm()
    bench.inject(SimFaultCode.HEATER_FAIL, 0.0)  # open element
    bench.hold = Setpoints(0.0, 0.0, 300.0, True)
    bench.step(40.0, dt_s=0.2)
    assert bench.node.state is NodeState.FAULT
    assert bench.node.first_fault is FaultCode.HEATER_VERIFY
    assert not bench.node.heater_on


def test_safety_11_over_temperature_trips_even_when_disabled(
    config: MillConfig, make_bench: Callable[..., Bench]
) -> None:
    small = config.model_copy(update={"furnace": config.furnace.model_copy(update={"heat_capacity_j_per_k": 50.0})})
    bench = make_bench(small, fault_injection=True)
    bench.step(0.05, heartbeat=False)
    bench.inject(SimFaultCode.HEATER_FAIL, 1.0)  # welded relay: full power whatever the node says
    bench.step(100.0, heartbeat=False, dt_s=0.5)
    assert bench.node.state is NodeState.FAULT
    assert bench.node.first_fault is FaultCode.OVERTEMP
    assert FaultFlag.OVERTEMP in bench.node.fault_bits

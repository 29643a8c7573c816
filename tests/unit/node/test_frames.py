"""What the node puts on the bus, frame by frame (``Node._frame``, ``Node._transmit``, the tick figures).

Each protected kind carries its own alive counter, one step per frame (the controller's E2E check reads a
repeated or skipped counter as a fault); each message's fields come from the model that owns them; a frame
lost on the way does not take the tick's other frames with it; and the node counts what it sent and what
failed to send (`millctl bus`, the benchmarks).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import can
import pytest

import firmware_sim.node
from millctl.protocol import (
    DriveTelemetry,
    FurnaceTelemetry,
    MillMessage,
    NodeStatus,
    PhysicsTelemetry,
    RefusalCode,
    Setpoints,
)

from .conftest import Bench

PROTECTED = (NodeStatus, DriveTelemetry, FurnaceTelemetry)
RATE_HZ = {NodeStatus: 20, DriveTelemetry: 50, FurnaceTelemetry: 10, PhysicsTelemetry: 10}
"""The DBC's cycle time of each periodic frame (tests/unit/node/test_telemetry.py checks them)."""


def of(bench: Bench, kind: type[MillMessage]) -> list[MillMessage]:
    return [d.message for d in bench.received if d.kind is kind and d.message is not None]


def test_each_protected_kind_steps_its_own_alive_counter_once_per_frame(bench: Bench) -> None:
    bench.step(2.0)
    for kind in PROTECTED:
        counters = [d.counter for d in bench.received if d.kind is kind]
        assert len(counters) > 16, kind.__name__  # at least one wrap of the 4-bit counter
        steps = {(b - a) % 16 for a, b in itertools.pairwise(counters) if a is not None and b is not None}
        assert steps == {1}, (kind.__name__, counters)


def test_the_drive_telemetry_carries_each_drives_torque_in_its_own_field(
    bench: Bench, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With the configured mill the estimates stay under half the wire's 0.1 N·m step; set apart here."""
    monkeypatch.setattr(bench.node.drives, "torques_nm", lambda: (1.2, -0.7))
    bench.step(0.1)
    frame = of(bench, DriveTelemetry)[-1]
    assert isinstance(frame, DriveTelemetry)
    assert (frame.rotary_torque_nm, frame.vibration_torque_nm) == pytest.approx((1.2, -0.7))


def test_the_furnace_telemetry_reports_the_furnace_model_as_the_tick_left_it(bench: Bench) -> None:
    """Temperature, setpoint, heater state and duty (in %, on the wire's 0.5 % step), each frame against the
    model right after the tick that sent it; the heater held a little above ambient runs at part duty."""
    bench.arm()
    bench.hold = Setpoints(0.0, 0.0, 27.0, True)
    compared = 0
    for _ in range(100):
        before = len(bench.received)
        bench.step(bench.tick_s)
        furnace = bench.node.furnace
        for decoded in bench.received[before:]:
            frame = decoded.message
            if not isinstance(frame, FurnaceTelemetry):
                continue
            assert frame.temp_c == pytest.approx(furnace.temp_c, abs=0.05 + 1e-9)
            assert frame.setpoint_c == pytest.approx(furnace.setpoint_c, abs=0.05 + 1e-9)
            assert frame.heater_on is furnace.heater_on
            assert frame.heater_pct == pytest.approx(furnace.duty * 100.0, abs=0.25 + 1e-9)
            compared += furnace.heater_on and 0.5 < furnace.duty < 1.0
    assert compared >= 5  # frames at part duty, where a wrong scale shows


def test_the_refusal_count_rolls_over_at_256_as_the_dbc_says(bench: Bench) -> None:
    bench.step(0.1)
    for _ in range(260):  # setpoints to a DISABLED node: each one refused
        bench.setpoints(0.0, 0.0)
    bench.step(0.1)
    status = bench.latest(NodeStatus)
    assert (status.refused_setpoints, status.last_refusal) == (260 % 256, RefusalCode.NOT_ARMED)


@pytest.mark.parametrize("lost", [NodeStatus, DriveTelemetry, FurnaceTelemetry, PhysicsTelemetry])
def test_a_frame_lost_on_the_way_does_not_take_the_ticks_other_frames_with_it(
    bench: Bench, monkeypatch: pytest.MonkeyPatch, lost: type[MillMessage]
) -> None:
    lost_id = bench.codec.frame_id(lost)
    transmit = bench.node.faults.transmit
    monkeypatch.setattr(bench.node.faults, "transmit",
                        lambda frame: None if frame.arbitration_id == lost_id else transmit(frame))
    bench.step(0.1)
    bench.received.clear()
    bench.step(2.0, dt_s=bench.config.timing.node_tick_s)
    for kind, hz in RATE_HZ.items():
        count = len(of(bench, kind))
        if kind is lost:
            assert count == 0
        else:
            assert abs(count - 2 * hz) <= 1, (kind.__name__, count)


def test_frames_sent_and_failed_sends_are_counted(bench: Bench, monkeypatch: pytest.MonkeyPatch) -> None:
    bench.step(0.5)
    assert bench.node.frames_sent == len(bench.frame_ids) > 0
    assert bench.node.tx_errors == 0
    send = bench.node.bus.send
    calls = itertools.count()

    def every_third_fails(message: can.Message, timeout: float | None = None) -> None:
        if next(calls) % 3 == 0:
            raise can.CanOperationError("transmit buffer full")
        send(message, timeout)

    monkeypatch.setattr(bench.node.bus, "send", every_third_fails)
    sent_before, seen_before = bench.node.frames_sent, len(bench.frame_ids)
    bench.step(0.5)
    attempts = next(calls)
    failed = (attempts + 2) // 3
    assert bench.node.tx_errors == failed > 0
    assert bench.node.frames_sent - sent_before == attempts - failed == len(bench.frame_ids) - seen_before


class TickTimer:
    """Stands in for the ``time`` module in firmware_sim.node: each tick takes the next of ``lengths`` (s)."""

    def __init__(self) -> None:
        self.lengths: list[float] = []
        self._reading = 0.0
        self._at_start = True

    def perf_counter(self) -> float:
        if not self._at_start:  # the end of a tick: it took the next length
            self._reading += self.lengths.pop(0)
        self._at_start = not self._at_start
        return self._reading


@pytest.fixture
def durations(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[float]]:
    """The lengths the node's next ticks take by the clock it times itself with (only its own ``time``)."""
    timer = TickTimer()
    monkeypatch.setattr(firmware_sim.node, "time", timer)
    yield timer.lengths


def test_the_tick_figures_count_each_tick_its_mean_and_its_longest(bench: Bench, durations: list[float]) -> None:
    durations.extend([0.001, 0.004, 0.002, 0.001])
    for _ in range(4):
        bench.node.tick()
    assert bench.node.tick_count == 4
    assert bench.node.tick_mean_s == pytest.approx(0.002)
    assert bench.node.tick_max_s == pytest.approx(0.004)

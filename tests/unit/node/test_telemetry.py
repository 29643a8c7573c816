"""The node's periodic frames: DBC rates, measured speeds, physics telemetry (level b)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable

from millctl.protocol import DriveTelemetry, FurnaceTelemetry, NodeStatus, PhysicsTelemetry

from .conftest import Bench


def test_periodic_frames_at_their_dbc_rates(bench: Bench) -> None:
    bench.step(0.05)
    bench.received.clear()
    bench.step(2.0, dt_s=bench.config.timing.node_tick_s)
    counts = Counter(d.kind for d in bench.received)
    for kind, hz in ((NodeStatus, 20), (DriveTelemetry, 50), (FurnaceTelemetry, 10), (PhysicsTelemetry, 10)):
        assert abs(counts[kind] - 2 * hz) <= 1, (kind.__name__, counts[kind])
    assert all(d.crc_ok for d in bench.received)


def test_drive_telemetry_reports_the_measured_speeds(bench: Bench) -> None:
    bench.run_at(80.0, 250.0)
    frame = bench.latest(DriveTelemetry)
    m_r, m_v = bench.node.measured_speeds_rpm
    assert abs(frame.rotary_rpm - m_r) <= 0.051 and abs(frame.vibration_rpm - m_v) <= 0.051
    assert abs(m_r - 80.0) < 3.0


def test_physics_telemetry_follows_the_operating_point(make_bench: Callable[..., Bench]) -> None:
    bench = make_bench(physics_worker="inline")
    bench.step(0.2)
    at_rest = bench.latest(PhysicsTelemetry)
    assert at_rest.detached is False and at_rest.no_slip_violated is False
    bench.arm()
    bench.ramp_to(120.0, 600.0)
    physics = bench.latest(PhysicsTelemetry)
    assert physics.detached is True
    assert physics.no_slip_violated is True  # issue 20: the carried rod slides before it leaves
    assert 0.0 < physics.theta_d_deg < 360.0
    assert physics.impact_rate_hz > 0.0 and physics.impact_energy_mj > 0.0 and physics.shear_kpa > 0.0
    assert bench.node.physics.computations < bench.node.tick_count / 5

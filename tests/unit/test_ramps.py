"""The ramp planner: every instant of every planned move stays inside the envelope."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from millctl.config import LimitLaw, MillConfig
from millctl.safety import Envelope, InterlockRefused
from millctl.safety.ramps import STANDSTILL, RampPlanner, SpeedPoint
from millctl.safety.wire import rounded_samples


def envelope_for(config: MillConfig, law: LimitLaw) -> Envelope:
    return Envelope.from_config(config, law=law)


@pytest.fixture(scope="module")
def planner(config: MillConfig) -> RampPlanner:
    return RampPlanner(Envelope.from_config(config))


def test_start_up_raises_vibration_before_rotation(planner: RampPlanner) -> None:
    move = planner.plan(STANDSTILL, SpeedPoint(180.0, 800.0))
    first, second = move.segments
    assert first.end == SpeedPoint(0.0, 800.0)  # ω_v first: eq. 9's limit rises with ω_v
    assert second.end == SpeedPoint(180.0, 800.0)
    assert move.duration_s == pytest.approx(800.0 / 120.0 + 180.0 / 40.0)


def test_stop_lowers_rotation_before_vibration(planner: RampPlanner) -> None:
    stop = planner.plan_stop(SpeedPoint(180.0, 800.0))
    assert stop.segments[0].end == SpeedPoint(0.0, 800.0)
    assert stop.end == STANDSTILL


def test_corrected_law_lowers_vibration_first_when_its_limit_falls(config: MillConfig) -> None:
    planner = RampPlanner(envelope_for(config, LimitLaw.CORRECTED_EVERY_PHASE))
    # at 900 rpm the every-phase limit is ~65 rpm; at 300 rpm it is ~200 rpm
    move = planner.plan(SpeedPoint(60.0, 900.0), SpeedPoint(150.0, 300.0))
    assert [s.end for s in move.segments] == [SpeedPoint(60.0, 300.0), SpeedPoint(150.0, 300.0)]


def test_over_limit_target_is_refused_with_reason(planner: RampPlanner) -> None:
    with pytest.raises(InterlockRefused, match=r"250\.0 rpm exceeds the limit 190\.0 rpm"):
        planner.plan(STANDSTILL, SpeedPoint(250.0, 800.0))


def test_rate_beyond_drive_is_refused(planner: RampPlanner) -> None:
    with pytest.raises(InterlockRefused, match="max_accel_rpm_s"):
        planner.plan(STANDSTILL, SpeedPoint(100.0, 800.0), rotary_rate_rpm_s=1000.0)


def test_target_at_the_edge_survives_snapping(planner: RampPlanner) -> None:
    edge = float(planner.envelope.omega_r_limit_rpm(800.0))
    with pytest.raises(InterlockRefused):
        planner.plan(STANDSTILL, SpeedPoint(edge + 0.04, 800.0))  # rounds above the limit
    assert planner.plan(STANDSTILL, SpeedPoint(edge - 0.05, 800.0)).end.omega_r_rpm <= edge


def inside_points(envelope: Envelope) -> st.SearchStrategy[SpeedPoint]:
    @st.composite
    def point(draw: st.DrawFn) -> SpeedPoint:
        w_v = draw(st.integers(0, int(envelope.vibration_max_rpm * 10))) / 10.0
        limit = float(envelope.omega_r_limit_rpm(w_v))
        top = int(limit * 10)
        w_r = draw(st.integers(0, max(top, 0))) / 10.0 if top > 0 else 0.0
        return SpeedPoint(w_r, w_v)

    return point()


@settings(max_examples=60, deadline=None)
@given(data=st.data(), law=st.sampled_from(list(LimitLaw)))
def test_every_instant_of_every_move_is_inside(config: MillConfig, data: st.DataObject, law: LimitLaw) -> None:
    envelope = envelope_for(config, law)
    planner = RampPlanner(envelope)
    start = data.draw(inside_points(envelope), label="start")
    target = data.draw(inside_points(envelope), label="target")
    rate_r = data.draw(st.floats(1.0, envelope.rotary_max_accel_rpm_s), label="rate_r")
    rate_v = data.draw(st.floats(1.0, envelope.vibration_max_accel_rpm_s), label="rate_v")
    for move in (planner.plan(start, target, rate_r, rate_v), planner.plan_stop(target)):
        assert move.end == planner.snap(move.end)
        times = [0.0, move.duration_s] + [s.t0_s for s in move.segments]
        times += [data.draw(st.floats(0.0, move.duration_s), label="t") for _ in range(5)]
        _, w_r, w_v = move.sample(dt_s=max(move.duration_s / 200.0, 1e-3))
        points = [move.at(t) for t in times] + [SpeedPoint(r, v) for r, v in zip(w_r, w_v, strict=True)]
        for p in points:
            # what the node receives: the point rounded onto the wire grid
            q = planner.snap(p)
            verdict = envelope.check(q.omega_r_rpm, q.omega_v_rpm)
            assert verdict.ok, (law, start, target, p, verdict.reason())


def test_linear_ramp_that_crosses_the_limit_midway_is_refused(planner: RampPlanner) -> None:
    start, target = SpeedPoint(140.0, 0.0), SpeedPoint(230.0, 1200.0)
    assert planner.envelope.check(140.0, 0.0).ok and planner.envelope.check(230.0, 1200.0).ok
    with pytest.raises(InterlockRefused, match=r"linear ramp at t = .* exceeds the limit"):
        planner.plan_linear(start, target)
    # the sequenced plan between the same ends is fine
    assert planner.plan(start, target).end == target


def test_linear_ramp_inside_is_one_segment(planner: RampPlanner) -> None:
    move = planner.plan_linear(SpeedPoint(100.0, 600.0), SpeedPoint(150.0, 800.0))
    assert len(move.segments) == 1
    assert move.duration_s == pytest.approx(max(50.0 / 40.0, 200.0 / 120.0))


def test_settle_dwell_between_one_axis_ramps(config: MillConfig) -> None:
    planner = RampPlanner(Envelope.from_config(config), settle_s=1.0)
    move = planner.plan(STANDSTILL, SpeedPoint(180.0, 800.0))
    _, dwell, _ = move.segments
    assert dwell.start == dwell.end == SpeedPoint(0.0, 800.0)
    assert dwell.t1_s - dwell.t0_s == 1.0
    assert move.duration_s == pytest.approx(800.0 / 120.0 + 1.0 + 180.0 / 40.0)


def test_linear_ramp_is_checked_on_the_wire_rounded_samples(planner: RampPlanner) -> None:
    """Issue 15 item 8: the line is inside, but (159.2, 459.7) on its way rounds outside: the node would refuse it."""
    start, target = SpeedPoint(174.0, 671.3), SpeedPoint(153.7, 382.0)
    env = planner.envelope
    assert env.check(159.2, 459.7).ok is False  # a rounded sample the line passes
    line_r = np.linspace(174.0, 153.7, 4001)
    line_v = np.linspace(671.3, 382.0, 4001)
    assert bool(np.all(env.contains(line_r, line_v)))  # the unrounded line is inside
    with pytest.raises(InterlockRefused, match=r"linear ramp at t = .* \(as sent, rounded to 0\.1 rpm\)"):
        planner.plan_linear(start, target)


@settings(max_examples=40, deadline=None)
@given(
    start=st.tuples(st.integers(0, 2500), st.integers(0, 12000)),
    end=st.tuples(st.integers(0, 2500), st.integers(0, 12000)),
)
def test_rounded_samples_hold_every_pair_a_sampled_line_can_send(start: tuple[int, int], end: tuple[int, int]) -> None:
    """The crossing enumeration contains every rounded pair that dense sampling of the line finds."""
    a, b = (start[0] / 10.0, start[1] / 10.0), (end[0] / 10.0, end[1] / 10.0)
    _, w_r, w_v = rounded_samples(a, b, 0.1)
    exact = set(zip(np.round(w_r, 6).tolist(), np.round(w_v, 6).tolist(), strict=True))
    f = np.linspace(0.0, 1.0, 20001)
    dense_r = np.round((a[0] + f * (b[0] - a[0])) / 0.1) * 0.1
    dense_v = np.round((a[1] + f * (b[1] - a[1])) / 0.1) * 0.1
    dense = set(zip(np.round(dense_r, 6).tolist(), np.round(dense_v, 6).tolist(), strict=True))
    assert dense <= exact


@settings(max_examples=60, deadline=None)
@given(data=st.data(), law=st.sampled_from(list(LimitLaw)))
def test_every_rounded_sample_of_an_accepted_linear_ramp_is_inside(
    config: MillConfig, data: st.DataObject, law: LimitLaw
) -> None:
    envelope = envelope_for(config, law)
    planner = RampPlanner(envelope)
    start = data.draw(inside_points(envelope), label="start")
    target = data.draw(inside_points(envelope), label="target")
    try:
        move = planner.plan_linear(start, target)
    except InterlockRefused:
        return
    _, w_r, w_v = move.sample(dt_s=max(move.duration_s / 3000.0, 1e-4))
    for r, v in zip(w_r, w_v, strict=True):
        q = planner.snap(SpeedPoint(float(r), float(v)))
        assert envelope.check(q.omega_r_rpm, q.omega_v_rpm).ok, (law, start, target, q)

"""The ramp planner: every instant of every planned move stays inside the envelope."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from millctl.config import LimitLaw, MillConfig
from millctl.safety import Envelope, InterlockRefused
from millctl.safety.ramps import STANDSTILL, RampPlanner, Segment, SpeedPoint, Trajectory, first_violation
from millctl.safety.wire import _crossings, first_wire_violation, rounded_samples


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
@example(start=(1740, 6713), end=(1537, 3820))  # issue 15 item 8: its line rounds outside on the wire
@example(start=(0, 0), end=(0, 0))  # a move of no length
@example(start=(0, 12000), end=(2500, 0))  # corner to corner, both axes at once
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


# --- the segments and their sampling -------------------------------------------------------------------------------


def test_a_segment_interpolates_between_its_instants_and_holds_its_ends_outside_them() -> None:
    a, b = SpeedPoint(100.0, 600.0), SpeedPoint(140.0, 800.0)
    segment = Segment(2.0, 4.0, a, b)
    assert segment.at(3.0) == SpeedPoint(120.0, 700.0)
    assert segment.at(2.5) == SpeedPoint(110.0, 650.0)
    assert segment.at(1.0) == a  # before it began
    assert segment.at(5.0) == b  # after it ended
    assert Segment(0.0, 0.5, a, b).at(0.25) == SpeedPoint(120.0, 700.0)  # a segment shorter than a second


def test_a_segment_of_no_duration_is_at_its_end() -> None:
    a, b = SpeedPoint(100.0, 600.0), SpeedPoint(140.0, 800.0)
    assert Segment(3.0, 3.0, a, b).at(3.0) == b
    assert Segment(3.0, 3.0, a, b).at(2.0) == b


def test_a_move_is_sampled_every_period_from_its_start_to_its_end() -> None:
    a, b = SpeedPoint(100.0, 600.0), SpeedPoint(140.0, 800.0)
    move = Trajectory(a, b, (Segment(0.0, 2.0, a, b),))
    times, w_r, w_v = move.sample(dt_s=0.5)
    assert times.tolist() == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert w_r.tolist() == [100.0, 110.0, 120.0, 130.0, 140.0]
    assert w_v.tolist() == [600.0, 650.0, 700.0, 750.0, 800.0]
    times, w_r, _ = move.sample(dt_s=10.0)  # a period longer than the move: its two ends
    assert times.tolist() == [0.0, 2.0]
    assert w_r.tolist() == [100.0, 140.0]


# --- what the planner refuses and how it plans ---------------------------------------------------------------------


def test_a_target_outside_is_refused_as_the_target(planner: RampPlanner) -> None:
    with pytest.raises(InterlockRefused, match=r"^target refused by the interlock: ω_r = 250\.0"):
        planner.plan(SpeedPoint(100.0, 800.0), SpeedPoint(250.0, 800.0))


def test_a_move_from_outside_the_envelope_is_refused_naming_its_start(planner: RampPlanner) -> None:
    with pytest.raises(InterlockRefused, match=r"^ramp start refused by the interlock: ω_r = 250\.0") as refused:
        planner.plan(SpeedPoint(250.0, 800.0), SpeedPoint(100.0, 800.0))
    assert refused.value.verdict == planner.envelope.check(250.0, 800.0)


def test_the_stop_is_planned_from_outside_the_envelope(planner: RampPlanner) -> None:
    """A mill found outside (a law changed under it, an over-speed) must still get its controlled stop."""
    outside = SpeedPoint(250.0, 800.0)
    assert not planner.envelope.check(250.0, 800.0).ok
    stop = planner.plan_stop(outside)
    assert [s.end for s in stop.segments] == [SpeedPoint(0.0, 800.0), STANDSTILL]
    assert stop.duration_s == pytest.approx(250.0 / 40.0 + 800.0 / 120.0)


def test_each_drive_ramps_at_its_own_requested_rate(planner: RampPlanner) -> None:
    move = planner.plan(STANDSTILL, SpeedPoint(180.0, 800.0), rotary_rate_rpm_s=20.0, vibration_rate_rpm_s=50.0)
    assert move.duration_s == pytest.approx(800.0 / 50.0 + 180.0 / 20.0)
    linear = planner.plan_linear(SpeedPoint(100.0, 600.0), SpeedPoint(150.0, 800.0), 10.0, 100.0)
    assert linear.duration_s == pytest.approx(50.0 / 10.0)  # the rotor is the slower one
    linear = planner.plan_linear(SpeedPoint(100.0, 600.0), SpeedPoint(150.0, 800.0), 40.0, 20.0)
    assert linear.duration_s == pytest.approx(200.0 / 20.0)  # vibration is the slower one


def test_a_linear_ramp_starts_at_its_start_at_once(planner: RampPlanner) -> None:
    start, target = SpeedPoint(100.0, 600.0), SpeedPoint(150.0, 800.0)
    move = planner.plan_linear(start, target)
    assert (move.start, move.end) == (start, target)
    assert [(s.t0_s, s.start, s.end) for s in move.segments] == [(0.0, start, target)]
    assert move.at(0.0) == start
    standing = planner.plan_linear(target, target)
    assert standing.segments == ()
    assert standing.duration_s == 0.0


def test_a_move_between_two_running_points_keeps_the_lower_rotor_speed(planner: RampPlanner) -> None:
    """Where the limit rises with ω_v the corridor's floor is the lower end's ω_r, not the limit at a lower ω_v."""
    env = planner.envelope
    assert planner.lowest_limit_rpm(1000.0, 800.0) == pytest.approx(env.limit_rpm(800.0))
    assert planner.lowest_limit_rpm(800.0, 1000.0) == pytest.approx(env.limit_rpm(800.0))
    assert env.limit_rpm(65.0) < 150.0  # the limit at a low ω_v is below both ends' ω_r
    move = planner.plan(SpeedPoint(150.0, 800.0), SpeedPoint(180.0, 1000.0))
    assert move.start == SpeedPoint(150.0, 800.0)
    assert [s.end for s in move.segments] == [SpeedPoint(150.0, 1000.0), SpeedPoint(180.0, 1000.0)]
    assert move.duration_s == pytest.approx(200.0 / 120.0 + 30.0 / 40.0)  # each ramp by its own change of speed


def test_the_wire_check_uses_the_planners_resolution(config: MillConfig) -> None:
    """On a 1 rpm grid this line rounds outside on its way; on the 0.1 rpm grid it does not."""
    start, target = SpeedPoint(165.0, 538.0), SpeedPoint(171.0, 631.0)
    envelope = Envelope.from_config(config)
    RampPlanner(envelope).plan_linear(start, target)
    with pytest.raises(InterlockRefused, match=r"\(as sent, rounded to 1 rpm\)"):
        RampPlanner(envelope, resolution_rpm=1.0).plan_linear(start, target)


def test_the_first_violation_is_judged_on_the_wires_grid_by_default(planner: RampPlanner) -> None:
    start, target = SpeedPoint(174.0, 671.3), SpeedPoint(153.7, 382.0)  # issue 15 item 8's line
    move = Trajectory(start, target, (Segment(0.0, 10.0, start, target),))
    found = first_violation(move, planner.envelope)
    assert found == first_violation(move, planner.envelope, 0.1)
    assert found is not None
    t_s, verdict = found
    assert t_s == pytest.approx(7.1673, abs=1e-4)
    assert verdict.refusals[0].value == pytest.approx(159.5)


def test_the_configured_planner_dwells_five_time_constants_of_the_slower_drive(config: MillConfig) -> None:
    drives = config.drives
    planner = RampPlanner.from_config(config)
    assert planner.settle_s == 5.0 * max(drives.rotary.time_constant_s, drives.vibration.time_constant_s)
    assert planner.resolution_rpm == 0.1
    assert planner.envelope == Envelope.from_config(config)
    corrected = envelope_for(config, LimitLaw.CORRECTED_EVERY_PHASE)
    assert RampPlanner.from_config(config, corrected).envelope is corrected


def test_the_margin_of_a_move_is_its_closest_approach_to_the_rotary_limit(planner: RampPlanner) -> None:
    env = planner.envelope
    move = planner.plan(STANDSTILL, SpeedPoint(180.0, 800.0))  # ω_v up at standstill, then ω_r up at 800 rpm
    assert move.min_margin_rpm(env) == pytest.approx(env.limit_rpm(800.0) - 180.0)
    assert move.min_margin_rpm(env, dt_s=0.01) == pytest.approx(env.limit_rpm(800.0) - 180.0)
    hold = planner.plan(SpeedPoint(100.0, 800.0), SpeedPoint(100.0, 1000.0))
    assert hold.min_margin_rpm(env) == pytest.approx(env.limit_rpm(800.0) - 100.0)  # lowest limit at its start
    assert planner.plan(STANDSTILL, SpeedPoint(0.0, 800.0)).min_margin_rpm(env) == math.inf  # the rotor never turns
    # a line runs closest to the (convex) limit between its ends: found within 0.001 rpm at the default 50 ms
    line = planner.plan_linear(SpeedPoint(140.0, 300.0), SpeedPoint(200.0, 1000.0))
    closest = line.min_margin_rpm(env, dt_s=0.001)
    assert closest < min(env.limit_rpm(300.0) - 140.0, env.limit_rpm(1000.0) - 200.0) - 1.0
    assert line.min_margin_rpm(env) == pytest.approx(closest, abs=1e-3)


# --- the wire's grid (millctl.safety.wire) -------------------------------------------------------------------------


def test_a_line_crosses_each_half_grid_boundary_strictly_between_its_ends() -> None:
    """Exact binary fractions: the boundaries of the 0.5 grid lie at 0.25, 0.75, 1.25, …"""
    assert _crossings(0.0, 1.0, 0.5).tolist() == [0.25, 0.75]
    assert sorted(_crossings(1.0, 0.0, 0.5).tolist()) == [0.25, 0.75]  # falling: the same boundaries
    assert _crossings(0.0, 2.0, 0.5).tolist() == [0.125, 0.375, 0.625, 0.875]
    assert _crossings(0.0, 0.5, 0.5).tolist() == [0.5]  # one boundary
    assert _crossings(0.25, 1.25, 0.5).tolist() == [0.5]  # boundaries at both ends are not crossings
    assert _crossings(-1.0, 0.0, 0.5).tolist() == [0.25, 0.75]  # the grid is the same below zero
    assert _crossings(0.1, 0.2, 0.5).tolist() == []  # between two boundaries
    assert _crossings(0.7, 0.7, 0.5).tolist() == []  # a point


def test_rounded_samples_are_each_stretch_between_crossings_and_both_mixes_at_each_crossing() -> None:
    """(0, 0) → (1, 0.5) on a 0.5 grid: ω_r crosses at f = ¼ and ¾, ω_v at ½ (worked by hand)."""
    fractions, w_r, w_v = rounded_samples((0.0, 0.0), (1.0, 0.5), 0.5)
    at = [0.0, 0.125, 0.375, 0.625, 0.875, 1.0]  # the ends and the middle of each stretch
    crossings = [0.25, 0.5, 0.75]
    assert fractions.tolist() == [*at, *crossings, *crossings]
    # the stretches, then each crossing with ω_r from before and ω_v from after, then the other way round
    assert w_r.tolist() == [*[0.0, 0.0, 0.5, 0.5, 1.0, 1.0], *[0.0, 0.5, 0.5], *[0.5, 0.5, 1.0]]
    assert w_v.tolist() == [*[0.0, 0.0, 0.0, 0.5, 0.5, 0.5], *[0.0, 0.5, 0.5], *[0.0, 0.0, 0.5]]


def test_the_first_wire_violation_is_the_earliest_over_every_segment(planner: RampPlanner) -> None:
    """The first segment is inside; in the second the earliest pair outside is a mix at a crossing (f = 5/12)."""
    env = planner.envelope
    corner, end = (183.5, 739.7), (184.1, 740.0)
    segments = [(0.0, 2.0, (150.0, 739.7), corner), (2.0, 14.0, corner, end)]
    assert first_wire_violation(segments[:1], env, 0.1) is None
    found = first_wire_violation(segments, env, 0.1)
    assert found is not None
    t_s, verdict = found
    assert t_s == pytest.approx(2.0 + 12.0 * 5.0 / 12.0)
    assert verdict.refusals[0].quantity == "omega_r"
    assert verdict.refusals[0].value == pytest.approx(183.8)


def test_a_planner_needs_a_positive_grid_and_a_dwell_not_below_zero(config: MillConfig) -> None:
    envelope = Envelope.from_config(config)
    with pytest.raises(ValueError, match=r"^resolution_rpm = 0\.0 must be > 0$"):
        RampPlanner(envelope, resolution_rpm=0.0)
    with pytest.raises(ValueError, match=r"^settle_s = -1\.0 must be ≥ 0$"):
        RampPlanner(envelope, settle_s=-1.0)
    assert RampPlanner(envelope, settle_s=0.0).settle_s == 0.0


def test_a_rate_beyond_the_drive_is_refused_as_the_ramp(planner: RampPlanner) -> None:
    with pytest.raises(InterlockRefused, match=r"^ramp refused by the interlock: omega_r_rate = 1000\.0 rpm/s"):
        planner.plan_linear(STANDSTILL, SpeedPoint(100.0, 800.0), rotary_rate_rpm_s=1000.0)

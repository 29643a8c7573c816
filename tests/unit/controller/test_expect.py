"""The stop ceiling starts from the highest of what was commanded and what was measured (controller.expect)."""

from __future__ import annotations

import pytest

from millctl.config import MillConfig
from millctl.controller.expect import SpeedExpectation
from millctl.safety import Envelope, RampPlanner, SpeedPoint

TOL = 3.0


@pytest.fixture
def expectation(config: MillConfig) -> SpeedExpectation:
    expect = SpeedExpectation(RampPlanner(Envelope.from_config(config)), TOL, 2.0, 3)
    expect.commanded(0.0, SpeedPoint(100.0, 400.0))
    expect.commanded(1.0, SpeedPoint(100.0, 400.0))
    return expect


def ceiling_at_start(expect: SpeedExpectation, measured: tuple[float, float] | None) -> tuple[float, float]:
    expect.begin_stop(1.0, measured)
    (_, r_high), (_, v_high) = expect.band(1.0)
    return r_high - TOL, v_high - TOL


def test_a_stop_ceiling_starts_from_what_was_commanded_when_the_drives_are_slower(
    expectation: SpeedExpectation,
) -> None:
    assert ceiling_at_start(expectation, (50.0, 200.0)) == pytest.approx((100.0, 400.0))


def test_a_stop_ceiling_starts_from_what_was_measured_when_the_drives_are_faster(expectation: SpeedExpectation) -> None:
    """A runaway drive is stopped from where it is, not from where it was told to be."""
    assert ceiling_at_start(expectation, (150.0, 500.0)) == pytest.approx((150.0, 500.0))


def test_a_stop_ceiling_with_nothing_measured_starts_from_what_was_commanded(expectation: SpeedExpectation) -> None:
    assert ceiling_at_start(expectation, None) == pytest.approx((100.0, 400.0))


# -- the band outside a stop: what was commanded over the lag window, widened by the tolerance -------------

WINDOW_S = 2.0
DEBOUNCE = 3


@pytest.fixture
def fresh(config: MillConfig) -> SpeedExpectation:
    """An expectation with nothing commanded yet (window 2 s, debounce 3, tolerance 3 rpm)."""
    return SpeedExpectation(RampPlanner(Envelope.from_config(config)), TOL, WINDOW_S, DEBOUNCE)


def test_with_nothing_commanded_the_band_is_standstill_within_the_tolerance(fresh: SpeedExpectation) -> None:
    assert fresh.band(0.0) == ((-TOL, TOL), (-TOL, TOL))
    assert fresh.stop is None
    assert fresh.stop_bound_s == WINDOW_S


def test_the_band_spans_every_pair_commanded_over_the_window_widened_by_the_tolerance(
    fresh: SpeedExpectation,
) -> None:
    fresh.commanded(0.0, SpeedPoint(100.0, 400.0))
    fresh.commanded(0.5, SpeedPoint(60.0, 700.0))
    fresh.commanded(1.0, SpeedPoint(80.0, 500.0))
    assert fresh.band(1.0) == ((60.0 - TOL, 100.0 + TOL), (400.0 - TOL, 700.0 + TOL))


def test_a_pair_commanded_again_at_the_same_instant_replaces_the_first(fresh: SpeedExpectation) -> None:
    fresh.commanded(0.0, SpeedPoint(10.0, 100.0))
    fresh.commanded(1.0, SpeedPoint(200.0, 900.0))
    fresh.commanded(1.0, SpeedPoint(20.0, 150.0))  # a revised command in the same tick
    assert fresh.band(1.0) == ((10.0 - TOL, 20.0 + TOL), (100.0 - TOL, 150.0 + TOL))


def test_the_window_keeps_the_pair_in_force_at_its_start_and_forgets_older_ones(fresh: SpeedExpectation) -> None:
    fresh.commanded(0.0, SpeedPoint(100.0, 800.0))
    fresh.commanded(1.0, SpeedPoint(50.0, 400.0))
    fresh.commanded(2.5, SpeedPoint(50.0, 400.0))  # the window starts at 0.5 s: (100, 800) was in force then
    assert fresh.band(2.5) == ((50.0 - TOL, 100.0 + TOL), (400.0 - TOL, 800.0 + TOL))
    fresh.commanded(3.0, SpeedPoint(50.0, 400.0))  # the window starts at 1.0 s, when (50, 400) took over
    assert fresh.band(3.0) == ((50.0 - TOL, 50.0 + TOL), (400.0 - TOL, 400.0 + TOL))


# -- the band during a stop: the controller's own stop plan, read one lag window late ---------------------


def test_the_stop_ceiling_holds_for_a_window_follows_the_plan_then_is_standstill(fresh: SpeedExpectation) -> None:
    fresh.commanded(0.0, SpeedPoint(100.0, 400.0))
    stop = fresh.begin_stop(1.0, None)
    assert stop.start == SpeedPoint(100.0, 400.0)
    assert fresh.stop_bound_s == pytest.approx(stop.duration_s + WINDOW_S)
    assert fresh.stop_end_s == pytest.approx(1.0 + stop.duration_s + WINDOW_S)
    assert fresh.band(1.0 + WINDOW_S) == ((-TOL, 100.0 + TOL), (-TOL, 400.0 + TOL))  # late by the window
    halfway = stop.at(stop.duration_s / 2.0)
    (_, r_high), (_, v_high) = fresh.band(1.0 + WINDOW_S + stop.duration_s / 2.0)
    assert (r_high - TOL, v_high - TOL) == pytest.approx((halfway.omega_r_rpm, halfway.omega_v_rpm))
    assert fresh.band(fresh.stop_end_s) == ((-TOL, TOL), (-TOL, TOL))


def test_a_stop_under_way_is_kept_when_another_begins(fresh: SpeedExpectation) -> None:
    fresh.commanded(0.0, SpeedPoint(100.0, 400.0))
    first = fresh.begin_stop(1.0, None)
    fresh.commanded(1.5, SpeedPoint(0.0, 0.0))
    assert fresh.begin_stop(1.5, (150.0, 600.0)) is first
    assert fresh.stop_end_s == pytest.approx(1.0 + first.duration_s + WINDOW_S)


def test_after_the_stop_the_band_is_what_was_commanded_again_once_the_ceiling_is_standstill(
    fresh: SpeedExpectation,
) -> None:
    fresh.commanded(0.0, SpeedPoint(100.0, 400.0))
    stop = fresh.begin_stop(1.0, None)
    fresh.commanded(1.0, SpeedPoint(0.0, 0.0))  # the controller commands standstill through a stop
    fresh.end_stop()
    assert fresh.stop is None
    assert fresh.band(1.0) == ((-TOL, 100.0 + TOL), (-TOL, 400.0 + TOL))  # the ceiling, a window late
    fresh.commanded(1.0 + WINDOW_S, SpeedPoint(20.0, 80.0))
    halfway = stop.at(stop.duration_s / 2.0)
    (_, r_high), (_, v_high) = fresh.band(1.0 + WINDOW_S + stop.duration_s / 2.0)  # the ceiling, read a window late
    assert (r_high - TOL, v_high - TOL) == pytest.approx(
        (max(20.0, halfway.omega_r_rpm), max(80.0, halfway.omega_v_rpm)))
    end_s = 1.0 + stop.duration_s + WINDOW_S
    fresh.commanded(end_s, SpeedPoint(20.0, 80.0))
    assert fresh.band(end_s + WINDOW_S) == ((20.0 - TOL, 20.0 + TOL), (80.0 - TOL, 80.0 + TOL))


# -- the judgement: above the band for the debounce count; at rest through a window though told to turn -----


def hold(expect: SpeedExpectation, point: SpeedPoint, until_s: float, dt_s: float = 0.1) -> None:
    """Command ``point`` every ``dt_s`` from 0 to ``until_s`` (as the controller's loop does)."""
    for i in range(round(until_s / dt_s) + 1):
        expect.commanded(i * dt_s, point)


@pytest.mark.parametrize("axis", [0, 1])
def test_a_drive_above_the_band_is_judged_at_the_debounce_count_and_its_edge_is_inside(
    fresh: SpeedExpectation, axis: int
) -> None:
    commanded = (100.0, 400.0)
    hold(fresh, SpeedPoint(*commanded), 1.0)
    edge = list(commanded)
    edge[axis] += TOL  # exactly the tolerance above: inside
    over = list(commanded)
    over[axis] += TOL + 0.1
    for _ in range(2 * DEBOUNCE):
        assert fresh.check(1.0, *edge) is None
    for _ in range(DEBOUNCE - 1):
        assert fresh.check(1.0, *over) is None
    assert fresh.check(1.0, *commanded) is None  # one sample inside: the count starts again
    for _ in range(DEBOUNCE - 1):
        assert fresh.check(1.0, *over) is None
    reason = fresh.check(1.0, *over)
    assert reason is not None
    assert "is not what was commanded" in reason and f"above it for {DEBOUNCE} samples in a row" in reason
    fresh.reset()
    assert fresh.check(1.0, *over) is None  # the count forgotten


def test_a_drive_above_the_stop_ceiling_is_judged_naming_the_ceiling(fresh: SpeedExpectation) -> None:
    fresh.commanded(0.0, SpeedPoint(100.0, 400.0))
    fresh.begin_stop(0.0, None)
    late = fresh.stop_end_s
    for _ in range(DEBOUNCE - 1):
        assert fresh.check(late, 2.0 * TOL, 0.0) is None
    reason = fresh.check(late, 2.0 * TOL, 0.0)
    assert reason == (  # the band as the operator reads it: a low edge below 0 rpm shown as 0
        "measured ω_r = 6.0 rpm, ω_v = 0.0 rpm is not the stop ceiling (ω_r 0.0…3.0 rpm, ω_v 0.0…3.0 rpm over the "
        "last 2.0 s: interlock.command_confirm_s + drive settle, tolerance 3.0 rpm); above it for 3 samples in a row"
    )


@pytest.mark.parametrize("axis", [0, 1])
@pytest.mark.parametrize(
    ("commanded_rpm", "judged"),
    [
        (10.0, False),  # below the at-rest threshold (5 tolerances): a drive this slow may read rest
        (5.0 * TOL, False),  # on the threshold: not over it
        (18.0, True),  # over it, though less than 5 tolerances above the band's low edge
        (100.0, True),
    ],
)
def test_a_drive_at_rest_though_commanded_to_turn_is_judged_after_a_whole_window(
    fresh: SpeedExpectation, axis: int, commanded_rpm: float, judged: bool
) -> None:
    point = [100.0, 400.0]
    point[axis] = commanded_rpm
    hold(fresh, SpeedPoint(*point), 10.0)
    reading = list(point)
    reading[axis] = TOL  # at rest: on the tolerance counts as rest
    start_s = 10.0 - WINDOW_S
    assert fresh.check(start_s, *reading) is None
    assert fresh.check(start_s + WINDOW_S / 2.0, *reading) is None
    reason = fresh.check(10.0, *reading)
    if not judged:
        assert reason is None
        return
    assert reason is not None and "the node did not take its setpoints" in reason
    assert f"below it for {WINDOW_S:.1f} s" in reason


def test_a_drive_that_turns_again_restarts_the_at_rest_window(fresh: SpeedExpectation) -> None:
    hold(fresh, SpeedPoint(100.0, 400.0), 10.0)
    assert fresh.check(7.0, 0.0, 400.0) is None
    assert fresh.check(8.0, 100.0, 400.0) is None  # turning: the window starts again
    assert fresh.check(8.5, 0.0, 400.0) is None
    assert fresh.check(10.0, 0.0, 400.0) is None  # 1.5 s at rest: less than the window
    assert fresh.check(10.5, 0.0, 400.0) is not None
    fresh.reset()
    assert fresh.check(10.5, 0.0, 400.0) is None  # forgotten: a whole window again


# -- after the node reports the stop done: the drives still settle under the ceiling -------------------------


def test_a_drive_settling_after_the_node_reported_the_stop_done_is_not_judged_until_the_ceiling_is_standstill(
    fresh: SpeedExpectation,
) -> None:
    """The node calls a drive at rest at ≤ the tolerance: a 2.9 rpm drive's noisy sensor then reads 3.6 (seen)."""
    hold(fresh, SpeedPoint(100.0, 400.0), 1.0)
    stop = fresh.begin_stop(1.0, None)
    for i in range(round((stop.duration_s + 0.2) / 0.1)):  # the controller commands standstill through the stop
        fresh.commanded(1.0 + 0.1 * (i + 1), SpeedPoint(0.0, 0.0))
    done_s = 1.0 + stop.duration_s + 0.2  # the node's report: its plan is over, its drives within the tolerance
    fresh.end_stop()
    assert fresh.stop is None

    def sample(at_s: float) -> str | None:  # the controller's tick: standstill commanded, then a reading judged
        fresh.commanded(at_s, SpeedPoint(0.0, 0.0))
        return fresh.check(at_s, 0.0, TOL + 0.6)

    assert [sample(done_s + 0.05 * i) for i in range(5)] == [None] * 5  # five noisy samples, 50 ms apart
    # once the ended stop's ceiling is standstill, the band is what was commanded: the same reading trips
    later_s = 1.0 + stop.duration_s + WINDOW_S
    verdicts = [sample(later_s + 0.05 * i) for i in range(DEBOUNCE)]
    assert verdicts[:-1] == [None] * (DEBOUNCE - 1)
    assert verdicts[-1] is not None and "is not what was commanded (" in verdicts[-1]


def test_a_new_stop_forgets_the_settling_of_the_last(fresh: SpeedExpectation) -> None:
    hold(fresh, SpeedPoint(100.0, 400.0), 1.0)
    first = fresh.begin_stop(1.0, None)
    fresh.end_stop()
    hold_s = 3.0  # the first stop's ceiling, a window late, is still 100/400 rpm here
    assert hold_s < 1.0 + first.duration_s + WINDOW_S
    for i in range(round(hold_s / 0.1)):
        fresh.commanded(1.0 + 0.1 * i, SpeedPoint(0.0, 0.0))
    fresh.commanded(hold_s, SpeedPoint(0.0, 0.0))
    assert fresh.band(hold_s) == ((-TOL, 100.0 + TOL), (-TOL, 400.0 + TOL))
    second = fresh.begin_stop(hold_s, (0.0, 0.0))  # a stop from standstill
    assert second.duration_s == 0.0
    fresh.end_stop()
    assert fresh.band(hold_s + WINDOW_S) == ((-TOL, TOL), (-TOL, TOL))

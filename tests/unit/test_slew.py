"""The rate bound over any window (millctl.safety.slew): sending more often buys nothing."""

from __future__ import annotations

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from millctl.safety.slew import SlewBudget

RATE, BURST = 60.0, 15.2  # rpm/s and rpm: the node's rotary drive (1.5 × 40 rpm/s, 0.25 s + 0.2 rpm)


def _walk(budget: SlewBudget, frames: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Send (dt, step) frames; return (time, position) after each, moving only on the steps allowed."""
    t, x, path = 0.0, 0.0, [(0.0, 0.0)]
    for dt, step in frames:
        t += dt
        if budget.allows(step, t):
            budget.spend(step, t)
            x += step
        path.append((t, x))
    return path


@given(
    st.lists(
        st.tuples(st.floats(0.0, 0.5), st.floats(-20.0, 20.0, allow_nan=False)),
        min_size=1,
        max_size=60,
    )
)
@example([(0.0, 20.0)] * 10)  # many frames at one instant: the burst, once
@example([(0.0, 20.0), (0.0, -20.0), (0.0, 20.0)])  # to and fro at one instant
@example([(0.5, 20.0)] * 60)  # a steady sender at the budget's pace
def test_accepted_steps_move_at_most_the_rate_over_any_window_plus_the_burst(frames: list[tuple[float, float]]) -> None:
    path = _walk(SlewBudget(RATE, BURST), frames)
    for i, (t1, x1) in enumerate(path):
        for t2, x2 in path[i + 1 :]:
            assert abs(x2 - x1) <= BURST + RATE * (t2 - t1) + 1e-9


@pytest.mark.parametrize("frame_rate_hz", [10.0, 100.0, 1000.0])
def test_sending_more_often_buys_nothing(frame_rate_hz: float) -> None:
    """A greedy sender asking for everything it can, from a full budget: the burst, then the rate (its first
    frame comes 1/f after the start, when the full budget could not refill)."""
    budget, t = SlewBudget(RATE, BURST), 0.0
    moved = 0.0
    for _ in range(int(frame_rate_hz)):
        t += 1.0 / frame_rate_hz
        step = budget.available(t)
        assert budget.allows(step, t) and not budget.allows(step + 0.01, t)
        budget.spend(step, t)
        moved += step
    assert moved == pytest.approx(BURST + RATE * (1.0 - 1.0 / frame_rate_hz))


def test_waiting_banks_at_most_the_burst_and_a_refill_restores_it() -> None:
    budget = SlewBudget(RATE, BURST)
    budget.spend(BURST, 0.0)
    assert budget.available(0.0) == 0.0
    assert budget.available(0.1) == pytest.approx(RATE * 0.1)
    assert budget.available(100.0) == BURST
    assert not budget.allows(-BURST - 0.1, 100.0)  # either sign
    budget.spend(BURST, 100.0)
    budget.refill(100.0)
    assert budget.available(100.0) == BURST


def test_a_step_larger_than_the_allowance_leaves_none_and_a_clock_going_back_adds_none() -> None:
    budget = SlewBudget(RATE, BURST)
    budget.spend(2 * BURST, 1.0)
    assert budget.available(1.0) == 0.0
    assert budget.available(0.5) == 0.0


@pytest.mark.parametrize(
    ("rate", "burst", "named"),
    [
        (0.0, 1.0, "slew rate 0.0/s"),
        (-1.0, 1.0, "slew rate -1.0/s"),
        (float("inf"), 1.0, "slew rate inf/s"),
        (float("nan"), 1.0, "slew rate nan/s"),
        (1.0, 0.0, "slew burst 0.0"),
        (1.0, -2.0, "slew burst -2.0"),
        (1.0, float("inf"), "slew burst inf"),
        (1.0, float("nan"), "slew burst nan"),
    ],
)
def test_a_budget_that_bounds_nothing_is_refused_naming_the_value(rate: float, burst: float, named: str) -> None:
    with pytest.raises(ValueError) as refused:
        SlewBudget(rate, burst)
    assert str(refused.value) == f"{named}: must be finite and > 0 (docs/operations.md#node-side-checks)"


@pytest.mark.parametrize(("rate", "burst"), [(0.01, 0.01), (0.5, 0.5)])
def test_any_positive_rate_and_burst_make_a_budget(rate: float, burst: float) -> None:
    budget = SlewBudget(rate, burst)
    assert budget.allows(burst, 0.0) and not budget.allows(burst * 1.01, 0.0)

"""The parts of millctl.bluesky that need no service: readiness, move verdicts, the lease keeper, recipes, plans."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from millctl.api import ControllerState, ControlOut, LeaseOut, RecipeCheckOut, StatusOut
from millctl.bluesky.link import (
    MillTripped,
    MoveInterrupted,
    Readiness,
    ServiceLink,
    _older,
    at_rest,
    move_failure,
    off_target_rpm,
    readiness,
)
from millctl.bluesky.plans import PreflightRefused, preflight
from millctl.bluesky.recipe_text import Hold, Ramp, recipe_toml
from millctl.bluesky.suspenders import SuspendWhenMillNotReady, reading_value
from millctl.config import load_config
from millctl.errors import InvalidInputError
from millctl.recipes import parse_recipe, plan_recipe

S = ControllerState


def status(state: ControllerState = S.RUNNING, **fields: Any) -> StatusOut:
    values: dict[str, Any] = {"state": state, "trip_cause": "", "target_rotary_rpm": 150.0,
                              "target_vibration_rpm": 800.0, "measured_rotary_rpm": 150.0,
                              "measured_vibration_rpm": 800.0, "furnace_target_c": None, "ramp_remaining_s": 0.0,
                              "time_s": 10.0}
    return StatusOut.model_construct(**{**values, **fields})


@pytest.mark.parametrize(("state", "staged", "holding", "expected"), [
    (S.TRIPPED, True, True, Readiness.TRIPPED),
    (S.TRIPPED, True, False, Readiness.TRIPPED),
    (S.RUNNING, True, False, Readiness.LEASE_LOST),
    (S.DISABLED, True, False, Readiness.LEASE_LOST),
    (S.RUNNING, True, True, Readiness.READY),
    (S.ARMED, False, False, Readiness.READY),
    (S.DISABLED, True, True, Readiness.NOT_ARMED),
    (S.STOPPING, True, True, Readiness.NOT_ARMED),
    (S.DISCONNECTED, False, False, Readiness.NOT_ARMED),
])
def test_readiness_of_each_state(state: ControllerState, staged: bool, holding: bool, expected: Readiness) -> None:
    assert readiness(state, staged=staged, holding=holding) is expected


def test_a_move_fails_on_a_trip_a_stop_or_setpoints_changed_by_another_command() -> None:
    assert move_failure(status(), 150.0, 800.0) is None
    tripped = move_failure(status(S.TRIPPED, trip_cause="ENVELOPE"), 150.0, 800.0)
    assert isinstance(tripped, MillTripped) and "ENVELOPE" in str(tripped)
    assert isinstance(move_failure(status(S.STOPPING), 150.0, 800.0), MoveInterrupted)
    changed = move_failure(status(target_rotary_rpm=100.0), 150.0, 800.0)
    assert isinstance(changed, MoveInterrupted) and "100.0/800.0" in str(changed)


def test_off_target_and_at_rest() -> None:
    assert off_target_rpm(status(measured_rotary_rpm=146.0), 150.0, 800.0) == pytest.approx(4.0)
    assert off_target_rpm(status(measured_vibration_rpm=None), 150.0, 800.0) is None
    resting = status(S.ARMED, target_rotary_rpm=0.0, target_vibration_rpm=0.0, measured_rotary_rpm=0.0,
                     measured_vibration_rpm=0.4)
    assert at_rest(resting)
    assert not at_rest(resting.model_copy(update={"measured_rotary_rpm": 3.0}))
    assert not at_rest(resting.model_copy(update={"furnace_target_c": 300.0}))


def test_a_status_taken_before_the_one_published_is_stale() -> None:
    newer = status(time_s=12.0)
    assert _older(status(time_s=11.5), newer)
    assert not _older(status(time_s=12.5), newer) and not _older(status(time_s=11.0), None)
    assert not _older(status(time_s=None), newer)


class FakeClient:
    """The lease calls of AsyncClient, against one lease held here."""

    def __init__(self) -> None:
        self.name = "bluesky@host"
        self.lease_id: str | None = None
        self.calls: list[str] = []

    async def take_control(self, force: bool = False) -> LeaseOut:
        self.calls.append("take")
        self.lease_id = "L1"
        return LeaseOut(lease_id="L1", holder=f"api:{self.name}", expires_in_s=30.0, ttl_s=30.0)

    async def release_control(self) -> ControlOut:
        self.calls.append("release")
        self.lease_id = None
        return ControlOut(held=False, holder=None, expires_in_s=None, expired=False)


def control(holder: str | None) -> ControlOut:
    return ControlOut(held=holder is not None, holder=holder, expires_in_s=None if holder is None else 20.0,
                      expired=False)


def test_the_keeper_gives_control_back_on_a_trip_and_takes_it_back_once_armed_and_free() -> None:
    client = FakeClient()
    link = ServiceLink(client)  # type: ignore[arg-type]
    ours = control("api:bluesky@host")

    async def scenario() -> None:
        await link.take()
        await link._keep_lease(status(), ours)
        assert link.holding and link.readiness is Readiness.NOT_ARMED  # no status polled yet
        await link._keep_lease(status(S.TRIPPED, trip_cause="STALL"), ours)
        assert not link.holding and "tripped" in link.lost_reason and client.calls == ["take", "release"]
        await link._keep_lease(status(S.DISABLED), control("api:operator@host"))  # the operator resets
        await link._keep_lease(status(S.DISABLED), control(None))  # reset, not armed: not ours yet
        assert not link.holding and client.calls == ["take", "release"]
        await link._keep_lease(status(S.ARMED), control(None))  # armed and released: ours again
        assert link.holding and client.calls == ["take", "release", "take"]
        await link._keep_lease(status(S.RUNNING), control("api:someone@else"))  # taken over
        assert not link.holding and "someone" in link.lost_reason

    asyncio.run(scenario())


def test_a_plan_becomes_a_recipe_the_pre_flight_accepts_or_refuses() -> None:
    config = load_config(None).config
    inside = recipe_toml("inside", [Ramp(150.0, 800.0), Hold(duration_s=10.0), Ramp(120.0, 400.0, 300.0),
                                    Hold(dose_kj_g=0.5)], note='quotes " and \\ kept')
    loaded = parse_recipe(inside, "inside.toml")
    assert [s.kind for s in loaded.recipe.steps] == ["ramp", "hold", "ramp", "hold"]
    assert loaded.recipe.recipe.operator_note == 'quotes " and \\ kept'
    assert plan_recipe(loaded.recipe, config).ok
    outside = plan_recipe(parse_recipe(recipe_toml("outside", [Ramp(250.0, 800.0), Hold(duration_s=1.0)]),
                                       "outside.toml").recipe, config)
    assert not outside.ok and "250" in str(outside.violations[0])
    with pytest.raises(InvalidInputError, match="exactly one"):
        Hold(duration_s=1.0, dose_kj_g=1.0)
    with pytest.raises(InvalidInputError, match="no steps"):
        recipe_toml("empty", [])


class CheckingClient:
    def __init__(self, answer: RecipeCheckOut) -> None:
        self.answer = answer
        self.sent: list[tuple[str, str]] = []

    async def recipe_check_text(self, name: str, text: str) -> RecipeCheckOut:
        self.sent.append((name, text))
        return self.answer


class StubMill:
    def __init__(self, client: CheckingClient) -> None:
        self.link = type("Link", (), {"client": client})()

    def require_link(self) -> Any:
        return self.link


def drive(plan: Any) -> Any:
    """Run a plan that only awaits (``wait_for``) without a RunEngine; return its result."""
    response: Any = None
    try:
        while True:
            msg = plan.send(response)
            assert msg.command == "wait_for", msg
            (factory,) = msg.args[0]

            async def run(f: Any = factory) -> asyncio.Task[Any]:
                task: asyncio.Task[Any] = asyncio.ensure_future(f())
                await asyncio.wait([task])
                return task

            response = [asyncio.run(run())]
    except StopIteration as stop:
        return stop.value


def check(ok: bool, problems: list[str]) -> RecipeCheckOut:
    return RecipeCheckOut(source="p", recipe="p", ok=ok, steps=2, planned_s=20.0, open_ended=False, dose_kj_g=None,
                          law="paper-eq9", problems=problems)


def test_the_pre_flight_refuses_a_plan_with_every_problem_before_anything_moves() -> None:
    refused = CheckingClient(check(False, ["step 1: ω_r 250 rpm over the limit 190 rpm", "step 2: too"]))
    with pytest.raises(PreflightRefused, match=r"before any move: step 1: ω_r 250 rpm.*; step 2: too") as raised:
        drive(preflight(StubMill(refused), "p", "TEXT"))  # type: ignore[arg-type]
    assert raised.value.check.problems[1] == "step 2: too"
    assert refused.sent == [("p", "TEXT")]
    accepted = CheckingClient(check(True, []))
    assert drive(preflight(StubMill(accepted), "p", "TEXT")).ok  # type: ignore[arg-type]


def test_the_suspender_trips_on_a_trip_or_a_lost_lease_and_resumes_only_when_ready() -> None:
    def reading(value: str) -> dict[str, dict[str, Any]]:
        return {"mill-readiness": {"value": value, "timestamp": 0.0}}

    assert reading_value(reading("READY")) == "READY"
    suspender = SuspendWhenMillNotReady.__new__(SuspendWhenMillNotReady)
    assert suspender._should_suspend(reading("TRIPPED")) and suspender._should_suspend(reading("LEASE_LOST"))
    assert not suspender._should_suspend(reading("NOT_ARMED")) and not suspender._should_resume(reading("NOT_ARMED"))
    assert suspender._should_resume(reading("READY")) and not suspender._should_suspend(reading("READY"))

"""The control loop's command queue: a request's command runs on the loop, a full queue or a loop that does not take
the command in time is answered 503 ``busy`` with nothing done, and an answer does not wait on a loop not running.

(The API fuzzer steps a runtime without its loop, tests/unit/service/test_schema.py: this is the loop's part.)
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest

import millctl.service.app
from millctl.clock import ManualClock
from millctl.config import load_config
from millctl.controller import Controller, ControllerState
from millctl.service import ServiceRuntime, create_app
from millctl.service.commands import OvertakenByStop
from millctl.service.runtime import COMMAND_QUEUE_SIZE, ServiceBusy
from tests.support.service import write_config

QUEUED_WITHIN_S = 30.0
"""A bound on the wait for the test's own threads to queue their commands (a safety net, not a measurement)."""


@pytest.fixture
def runtime(tmp_path: Path) -> Iterator[ServiceRuntime]:
    running = ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False)
    running.start()
    try:
        yield running
    finally:
        running.close()


def test_a_command_runs_on_the_control_loop(runtime: ServiceRuntime) -> None:
    ran_on: list[str] = []

    def action(c: Controller) -> int:
        ran_on.append(threading.current_thread().name)
        return 7

    assert runtime.call(action, needs_node=False) == 7
    assert ran_on == ["millctl-control-loop"]


def test_a_command_the_loop_does_not_take_in_time_is_busy_and_never_runs(runtime: ServiceRuntime) -> None:
    ran: list[bool] = []
    busy = pytest.raises(ServiceBusy, match=r"did not take the command within .* \(nothing was done\)")
    with runtime.lock, busy:  # the loop waits for the lock in its tick: it takes no command
        runtime.call(lambda c: ran.append(True), needs_node=False, timeout_s=0.05)
    assert runtime.call(lambda c: "after", needs_node=False) == "after"  # the loop runs on, and ran what came after
    assert ran == []


def test_a_full_queue_is_busy_at_once_and_the_queued_commands_all_run(runtime: ServiceRuntime) -> None:
    done: list[int] = []
    waiting: list[threading.Thread] = []
    with runtime.lock:
        for i in range(COMMAND_QUEUE_SIZE):
            thread = threading.Thread(target=lambda i=i: runtime.call(lambda c: done.append(i), needs_node=False))
            thread.start()
            waiting.append(thread)
        deadline = time.monotonic() + QUEUED_WITHIN_S
        while runtime._commands.qsize() < COMMAND_QUEUE_SIZE:
            assert time.monotonic() < deadline, f"{runtime._commands.qsize()} of {COMMAND_QUEUE_SIZE} queued"
            time.sleep(0.01)
        assert not done
        with pytest.raises(ServiceBusy, match=f"has {COMMAND_QUEUE_SIZE} commands waiting.*nothing was done"):
            runtime.call(lambda c: done.append(-1), needs_node=False)
    for thread in waiting:
        thread.join(QUEUED_WITHIN_S)
    assert sorted(done) == list(range(COMMAND_QUEUE_SIZE))


async def test_an_answer_does_not_wait_for_a_state_when_no_loop_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A runtime whose loop is not running (never started here) answers arm at once: nothing would tick to ARMED."""
    stepped = ServiceRuntime(load_config(write_config(tmp_path)), clock=ManualClock())
    try:
        for _ in range(100):  # 1 s of mill time: the controller hears the embedded node
            stepped.tick()
            assert isinstance(stepped.clock, ManualClock)
            stepped.clock.advance(stepped.config.timing.controller_tick_s)
        assert stepped.controller.state is ControllerState.DISABLED
        lease = stepped.leases.take("test")[0].lease_id

        def no_wait(seconds: float) -> None:
            raise AssertionError(f"the answer waited ({seconds} s) on a runtime whose loop is not running")

        monkeypatch.setattr(millctl.service.app, "time", type("Time", (), {"monotonic": time.monotonic,
                                                                             "sleep": staticmethod(no_wait)}))
        transport = httpx.ASGITransport(app=create_app(stepped))
        async with httpx.AsyncClient(transport=transport, base_url="http://mill") as client:
            answer = await client.post("/v1/arm", headers={"X-Millctl-Lease": lease})
        assert answer.status_code == 200, answer.text
        assert answer.json()["state"] != ControllerState.ARMED  # as it was, nothing ticked
    finally:
        stepped.close()


def _fill_the_queue(runtime: ServiceRuntime, done: list[int], errors: list[BaseException]) -> list[threading.Thread]:
    """With the loop held (the caller holds its lock), queue COMMAND_QUEUE_SIZE commands, each recording its index
    in ``done`` when it runs, or what it raised in ``errors``."""
    waiting: list[threading.Thread] = []

    def queue_one(i: int) -> None:
        try:
            runtime.call(lambda c: done.append(i), needs_node=False)
        except BaseException as exc:  # kept for the test to read
            errors.append(exc)

    for i in range(COMMAND_QUEUE_SIZE):
        thread = threading.Thread(target=queue_one, args=(i,))
        thread.start()
        waiting.append(thread)
    deadline = time.monotonic() + QUEUED_WITHIN_S
    while runtime._commands.qsize() < COMMAND_QUEUE_SIZE:
        assert time.monotonic() < deadline, f"{runtime._commands.qsize()} of {COMMAND_QUEUE_SIZE} queued"
        time.sleep(0.01)
    return waiting


def _in_thread(run: Callable[[], object]) -> tuple[threading.Thread, list[object]]:
    got: list[object] = []

    def target() -> None:
        try:
            got.append(run())
        except BaseException as exc:  # the test reads it
            got.append(exc)

    thread = threading.Thread(target=target)
    thread.start()
    return thread, got


def test_a_stop_with_the_command_queue_full_is_not_busy_and_runs_first(runtime: ServiceRuntime) -> None:
    """STOP and E-stop take a queue of their own, never full and served first (SAFETY 24; issue 37, defect 3)."""
    done: list[int] = []
    errors: list[BaseException] = []
    with runtime.lock:
        waiting = _fill_the_queue(runtime, done, errors)
        stop, got = _in_thread(lambda: asyncio.run(runtime.call_urgent(lambda c: done.append(-1))))
        deadline = time.monotonic() + QUEUED_WITHIN_S
        while runtime.paths.urgent.qsize() < 1 and not got:
            assert time.monotonic() < deadline, "the stop was never queued"
            time.sleep(0.01)
        assert not got, got  # queued, not refused busy
    stop.join(QUEUED_WITHIN_S)
    for thread in waiting:
        thread.join(QUEUED_WITHIN_S)
    assert got == [None]
    assert done[0] == -1 and sorted(done[1:]) == list(range(COMMAND_QUEUE_SIZE))


def test_a_stop_refuses_the_commands_waiting_behind_it(runtime: ServiceRuntime) -> None:
    """Stop wins over start: what was queued when a stop arrived is refused, nothing of it done."""
    done: list[int] = []
    errors: list[BaseException] = []
    with runtime.lock:
        waiting = _fill_the_queue(runtime, done, errors)
        stop, got = _in_thread(lambda: asyncio.run(runtime.call_urgent(lambda c: done.append(-1),
                                                                       stops="api:operator")))
        deadline = time.monotonic() + QUEUED_WITHIN_S
        while runtime.paths.urgent.qsize() < 1:
            assert time.monotonic() < deadline, "the stop was never queued"
            time.sleep(0.01)
    stop.join(QUEUED_WITHIN_S)
    for thread in waiting:
        thread.join(QUEUED_WITHIN_S)
    assert done == [-1] and got == [None]
    assert len(errors) == COMMAND_QUEUE_SIZE and all(isinstance(e, OvertakenByStop) for e in errors), errors[:2]
    assert "a stop by api:operator arrived while it waited" in str(errors[0])
    assert runtime.call(lambda c: "after", needs_node=False) == "after"  # commands after the stop run


def test_a_status_read_takes_no_slot_of_a_full_command_queue(runtime: ServiceRuntime) -> None:
    """Reads are answered from the loop's snapshot: a full command queue refuses none (issue 37, defect 3)."""
    done: list[int] = []
    errors: list[BaseException] = []
    with runtime.lock:
        waiting = _fill_the_queue(runtime, done, errors)
        read, got = _in_thread(runtime.status)
        time.sleep(0.05)
        assert not any(isinstance(g, ServiceBusy) for g in got), got
    read.join(QUEUED_WITHIN_S)
    for thread in waiting:
        thread.join(QUEUED_WITHIN_S)
    assert len(got) == 1 and isinstance(got[0], dict) and got[0]["state"] == "DISCONNECTED", got

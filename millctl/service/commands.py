"""The three paths from a request to the control loop, so that no client can crowd out another's command (SAFETY 24).

* **STOP and E-stop** (:meth:`LoopPaths.call_urgent`) go to a queue that is
  never full and is served first, all of it, every tick; the request awaits
  its answer on the server's event loop, taking no thread of its pool.
* **Other commands** (:meth:`LoopPaths.call`) go to a bounded queue; a full
  queue is refused at once (503 ``busy``), with nothing done.
* **Status reads** (:meth:`LoopPaths.snapshot`) take no queue slot: the loop
  publishes a snapshot after its commands, and a read is answered from it
  (one fresher than STATUS_MAX_AGE_S is asked for, and published at the next
  tick).

On the old single queue, 50 clients polling the status had setpoint commands
refused busy (issue 37). Request handlers never touch the controller and never
hold the loop's lock: the loop runs what they queue (SAFETY 19).
"""

from __future__ import annotations

import asyncio
import math
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from typing import Any, TypeVar

from millctl.api import RecipeOut
from millctl.controller import Controller
from millctl.errors import BusError, InterlockError

T = TypeVar("T")

COMMAND_QUEUE_SIZE = 32
"""Commands waiting for the control loop; one more is refused at once (503 ``busy``). Reads, STOP and E-stop
take no slot here."""
COMMANDS_PER_TICK = 8
"""The loop runs at most this many queued commands after each tick."""
URGENT_PER_TICK = 4096
"""The loop runs at most this many STOPs and E-stops after each tick: more than the service has connections
(millctl.service.connections), so every one waiting is run at the next tick."""
COMMAND_TIMEOUT_S = 5.0
"""A request waits this long for the loop to run its command before it is answered 503 (s)."""
STATUS_MAX_AGE_S = 0.05
"""A status read is answered from the loop's snapshot when it is at most this old (s); else the next tick's."""

Snapshot = tuple[dict[str, Any], RecipeOut]
"""What reads are answered from: the status (JSON-ready) and the recipe run's progress."""
_Command = tuple[Callable[[Controller], Any], bool, "Future[Any]"]
_Urgent = tuple[Callable[[Controller], Any], bool, "Future[Any]", str | None]
"""An urgent command, and who stops (None: not a stop): a stop overtakes every command waiting behind it."""


class NodeUnreachable(BusError):
    """The controller has not heard from the node (or the control loop is down): nothing can be commanded."""


class ServiceBusy(BusError):
    """The control loop's command queue is full, or it did not take the command in time (HTTP 503)."""


class OvertakenByStop(InterlockError):
    """A command that was waiting when a STOP or E-stop arrived: not run, stop wins over start (HTTP 409)."""


class LoopPaths:
    """The queues and the snapshot between the request handlers and the control loop of one runtime.

    ``execute(action, needs_node)`` runs a command on the loop (under its lock); ``take_snapshot()`` makes the
    snapshot; ``failed()`` says why the loop ended, if it did.
    """

    def __init__(
        self,
        lock: threading.RLock,
        execute: Callable[[Callable[[Controller], Any], bool], Any],
        take_snapshot: Callable[[], Snapshot],
        failed: Callable[[], str | None],
    ) -> None:
        self.lock = lock
        self._execute = execute
        self._take_snapshot = take_snapshot
        self._failed = failed
        self.thread: threading.Thread | None = None
        """The loop's thread (:meth:`attach`); until it runs, commands and reads are served in the caller."""
        self.commands: queue.Queue[_Command] = queue.Queue(maxsize=COMMAND_QUEUE_SIZE)
        self.urgent: queue.SimpleQueue[_Urgent] = queue.SimpleQueue()
        """STOP and E-stop: never full (each waits on a connection, and those are bounded), served first."""
        self._published = threading.Condition()
        self._snapshot: Snapshot | None = None
        self._snapshot_s = -math.inf
        self._wanted = False

    def attach(self, thread: threading.Thread) -> None:
        """The loop's thread, which runs :meth:`run` after each tick."""
        self.thread = thread

    def _loop_alive(self) -> bool:
        return self.thread is not None and self.thread.is_alive()

    def _in_caller(self, action: Callable[[Controller], T], needs_node: bool) -> T:
        """No loop to ask (not started, or ended), or the loop itself: here, under the lock."""
        if self.thread is not None and self.thread.ident is not None and needs_node:
            raise NodeUnreachable(self._failed() or "the control loop is not running")
        with self.lock:
            result: T = self._execute(action, needs_node)
            return result

    # ------------------------------------------------------------------ on the loop
    def run(self) -> None:
        """Run the queued commands (STOPs and E-stops first, all of them), then publish the snapshot, under the lock.

        The snapshot is published before the answers are handed back, so a read that follows a command's answer
        sees what the command did.
        """
        answers: list[tuple[Future[Any], Any, BaseException | None]] = []
        with self.lock:
            stoppers: list[str] = []
            for _ in range(URGENT_PER_TICK):
                try:
                    action, needs_node, future, stopper = self.urgent.get_nowait()
                except queue.Empty:
                    break
                if stopper is not None:
                    stoppers.append(stopper)
                self._answer(answers, future, action, needs_node)
            if stoppers:  # stop wins over start: what waited behind a stop is not run
                overtaken = OvertakenByStop(f"not run: a stop by {', '.join(dict.fromkeys(stoppers))} arrived while "
                                            "it waited (stop wins over start); nothing was done")
                while True:
                    try:
                        _, _, future = self.commands.get_nowait()
                    except queue.Empty:
                        break
                    if future.set_running_or_notify_cancel():
                        answers.append((future, None, overtaken))
            for _ in range(COMMANDS_PER_TICK):
                try:
                    action, needs_node, future = self.commands.get_nowait()
                except queue.Empty:
                    break
                self._answer(answers, future, action, needs_node)
            if answers or self._wanted:
                snapshot = self._take_snapshot()
                with self._published:
                    self._snapshot, self._snapshot_s, self._wanted = snapshot, time.monotonic(), False
                    self._published.notify_all()
        for future, result, error in answers:
            if error is None:
                future.set_result(result)
            else:
                future.set_exception(error)

    def _answer(self, answers: list[tuple[Future[Any], Any, BaseException | None]], future: Future[Any],
                action: Callable[[Controller], Any], needs_node: bool) -> None:
        if not future.set_running_or_notify_cancel():
            return  # its request gave up waiting
        try:
            answers.append((future, self._execute(action, needs_node), None))
        except BaseException as exc:  # handed to the waiting request, which maps it to its 4xx/5xx
            answers.append((future, None, exc))

    # ------------------------------------------------------------------ from the request handlers
    def call(self, action: Callable[[Controller], T], *, needs_node: bool = True,
             timeout_s: float = COMMAND_TIMEOUT_S) -> T:
        """Have the loop run ``action(controller)`` after its next tick; refused at once when the queue is full."""
        if threading.current_thread() is self.thread or not self._loop_alive():
            return self._in_caller(action, needs_node)
        future: Future[T] = Future()
        try:
            self.commands.put_nowait((action, needs_node, future))
        except queue.Full:
            raise ServiceBusy(
                f"the control loop has {COMMAND_QUEUE_SIZE} commands waiting: try again (nothing was done)"
            ) from None
        try:
            return future.result(timeout=timeout_s)
        except FutureTimeout:
            if future.cancel():
                raise ServiceBusy(f"the control loop did not take the command within {timeout_s:.0f} s "
                                  "(nothing was done)") from None
            return future.result()  # it started just now: its result is on the way

    async def call_urgent(self, action: Callable[[Controller], T], *, needs_node: bool = False,
                          stops: str | None = None, timeout_s: float = COMMAND_TIMEOUT_S) -> T:
        """Have the loop run ``action(controller)`` (a STOP, an E-stop) before anything else at its next tick.

        ``stops`` names who stops: then every command waiting in the command queue is refused, not run
        (:class:`OvertakenByStop`): stop wins over start.

        Never refused as busy: the queue is never full, and the request awaits the answer on the server's event
        loop, taking no thread of its pool. A loop that does not take it within ``timeout_s`` is stalled or dead:
        503 ``node_unreachable``, and the command stays queued (a late stop is still a stop; the node's watchdog
        stops the mill once the heartbeat stops).
        """
        if not self._loop_alive():
            return self._in_caller(action, needs_node)
        future: Future[T] = Future()
        self.urgent.put((action, needs_node, future, stops))
        try:
            return await asyncio.wait_for(asyncio.shield(asyncio.wrap_future(future)), timeout_s)
        except TimeoutError:
            raise NodeUnreachable(f"the control loop did not take the command within {timeout_s:.0f} s: it is "
                                  "stalled or gone; the command stays queued, and the node's watchdog stops the "
                                  "mill once the heartbeat stops") from None

    def call_soon(self, action: Callable[[Controller], Any]) -> None:
        """Queue ``action(controller)`` first for the loop without waiting (from the records thread; never raises)."""
        self.urgent.put((action, False, Future(), None))

    def snapshot(self, timeout_s: float = COMMAND_TIMEOUT_S) -> Snapshot:
        """Status and recipe progress as the loop published them: a read takes no slot of the command queue.

        Answered from the snapshot the loop published when that is at most STATUS_MAX_AGE_S old, else from the
        one the loop publishes at its next tick (asked for here).
        """
        if not self._loop_alive():
            with self.lock:
                return self._take_snapshot()
        asked_s = time.monotonic()
        with self._published:
            if self._snapshot is not None and asked_s - self._snapshot_s <= STATUS_MAX_AGE_S:
                return self._snapshot
            self._wanted = True
            if not self._published.wait_for(lambda: self._snapshot_s >= asked_s or not self._loop_alive(),
                                            timeout_s):
                raise ServiceBusy(f"the control loop published no status within {timeout_s:.0f} s")
            if self._snapshot is None or self._snapshot_s < asked_s:
                raise NodeUnreachable(self._failed() or "the control loop is not running")
            return self._snapshot


__all__ = [
    "COMMANDS_PER_TICK",
    "COMMAND_QUEUE_SIZE",
    "COMMAND_TIMEOUT_S",
    "STATUS_MAX_AGE_S",
    "URGENT_PER_TICK",
    "LoopPaths",
    "NodeUnreachable",
    "OvertakenByStop",
    "ServiceBusy",
    "Snapshot",
]

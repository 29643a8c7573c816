"""The service's runtime: one control-loop thread owning the controller, the embedded node and the recipe runner.

Every ``timing.controller_tick_s`` the loop ticks the controller, the recipe
runner and the node (when embedded), then runs the commands waiting for it.
Request handlers never touch the controller themselves and never hold the
loop's lock: they queue a command and wait for its result, so a slow request
(a huge body, a slow client) cannot delay a heartbeat (SAFETY 19). STOP and
E-stop, other commands and status reads take three paths, so that no client
can crowd out another's command (:mod:`.commands`, SAFETY 24). Records
(events, run records, the bus log) are written on a thread of their own
(:class:`~millctl.records.RecordQueue`): a full or failing disk is a warning and
an event, a running recipe is stopped in a controlled way, and the mill stays
controlled (SAFETY 23). If the loop dies, the heartbeat stops and the node's
watchdog stops the mill (SAFETY 2): the service never keeps commanding
without its loop.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from typing import Any, TypeVar

import can

from millctl import __version__
from millctl.api import EventKind, RecipeOut, ServiceOut
from millctl.clock import Clock, MonotonicClock
from millctl.config.loader import LoadedConfig
from millctl.config.paths import service_paths
from millctl.controller import STANDSTILL_RPM, Controller, ControllerState
from millctl.protocol import RotatingBusLog, open_bus
from millctl.records import RecordQueue
from millctl.service.commands import (
    COMMAND_QUEUE_SIZE,
    COMMAND_TIMEOUT_S,
    STATUS_MAX_AGE_S,
    LoopPaths,
    NodeUnreachable,
    ServiceBusy,
    Snapshot,
)
from millctl.service.faults import embeds_node, require_simulated
from millctl.service.host import HostWatch, realtime_policy_problem
from millctl.service.journal import Journal, finite
from millctl.service.lease import DEFAULT_TTL_S, LeaseManager
from millctl.service.recipe import RecipeSlot
from millctl.service.tap import TappedBus

log = logging.getLogger(__name__)

T = TypeVar("T")
S = ControllerState

BUS_LOG_STEM = "bus"
"""The candump bus log of each session: ``<records_dir>/bus/bus_<start time>.log``."""

EMBEDDED_NODE_WAIT_S = 10.0
"""With the embedded node, the API opens once the controller has seen it (or after this long, s)."""

STOP_BOUND_S = (5.0, 30.0)
"""A shutdown waits for standstill the expected ramp-down time plus 2 s, kept within these bounds (s)."""


class ServiceRuntime:
    """Owns the bus, the controller, the optional embedded node, the lease, the journal and the loop thread."""

    def __init__(
        self,
        loaded: LoadedConfig,
        *,
        clock: Clock | None = None,
        embed_node: bool | None = None,
        lease_ttl_s: float = DEFAULT_TTL_S,
        fault_injection: bool = False,
    ) -> None:
        self.loaded = loaded
        config = self.config = loaded.config
        if fault_injection:
            require_simulated(config, embed_node)  # before anything is opened
        self.fault_injection = fault_injection
        """An instructor may inject the embedded node's faults (``/v1/sim/faults``; :mod:`.faults`)."""
        service = config.service
        self.clock = clock or MonotonicClock()
        self.records_dir = service_paths(loaded).records_dir
        self.started_unix = time.time()
        self.socket_path = ""
        """The socket the API is served on (set by :func:`millctl.service.serve`)."""
        self.records_warning: str | None = None
        self.bus_warnings: list[str] = []
        """What is wrong with the CAN link as the service started (socketcan: its bitrate, its state)."""
        """Why records cannot be written now (None while they can): shown in the status."""
        self.records = RecordQueue(on_change=self._records_changed)
        self.journal = Journal(self.records_dir, rotate_bytes=service.rotate_bytes, keep_files=service.keep_files,
                               queue=self.records)
        self.lock = threading.RLock()
        self.leases = LeaseManager(self.clock, lease_ttl_s)
        self.failed: str | None = None
        self.stopping = False
        self.paths = LoopPaths(self.lock, self._execute, self._take_snapshot, lambda: self.failed)
        self._commands = self.paths.commands
        session = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime(self.started_unix))
        self.bus_log_path = self.records_dir / "bus" / f"{BUS_LOG_STEM}_{session}_{os.getpid()}.log"
        bus_log = RotatingBusLog(self.bus_log_path, service.rotate_bytes, service.keep_files)
        self.bus = TappedBus(open_bus(config.bus), bus_log, channel=config.bus.channel, records=self.records)
        self.furnace_bus: TappedBus | None = None
        """The furnace node's own channel beside CiA 402 drives, in the same bus log under its channel's name."""
        if config.drives.furnace_bus is not None:
            furnace = config.drives.furnace_bus
            self.furnace_bus = TappedBus(open_bus(furnace), bus_log, channel=furnace.channel, records=self.records)
        self.controller = Controller(config, self.bus, self.clock, listener=self.journal.on_event,
                                     furnace_bus=self.furnace_bus)
        self.node: Any = None
        self._node_bus: can.BusABC | None = None
        if embeds_node(config, embed_node):
            from firmware_sim.embedded import simulated_mill  # the millbus node or the CiA 402 drives

            self._node_bus = open_bus(config.bus)
            self.node = simulated_mill(config, self._node_bus, self.clock, fault_injection=fault_injection)
        self.recipe = RecipeSlot(self.controller, self.clock, self.records_dir, loaded.sha256, records=self.records)
        self.host = HostWatch(config, self.journal.add)
        """The control loop's lateness, its warnings and host-starvation trips; systemd's watchdog (SAFETY 27)."""
        self.recipe.sample_extra = self.host.sample  # the run report plots the loop's lateness beside the speeds
        self.realtime_problem: str | None = None
        """Why the service has no real-time scheduling policy (None when it has one); set at start."""
        self._halt = threading.Event()
        self._closed = False
        self._thread = threading.Thread(target=self._loop, name="millctl-control-loop", daemon=True)
        self.paths.attach(self._thread)

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> None:
        """Record the start and the configuration (SAFETY 14: law and margin shown), then start the loop."""
        envelope = self.controller.envelope
        self.journal.add(EventKind.SERVICE, "service", f"service started (pid {os.getpid()}, millctl {__version__})",
                         pid=os.getpid(), version=__version__)
        self.journal.add(
            EventKind.CONFIG,
            "service",
            f"config {self.loaded.source} (sha256 {self.loaded.sha256[:12]}…): envelope {envelope.description}",
            path=self.loaded.source,
            sha256=self.loaded.sha256,
            law=envelope.law.value,
            margin=envelope.margin,
            bus_interface=self.config.bus.interface,
            bus_channel=self.config.bus.channel,
            embedded_node=self.node is not None,
        )
        from millctl.protocol.bus_check import startup_link_problems

        self.realtime_problem = realtime_policy_problem()
        if self.realtime_problem is not None:
            log.warning("%s", self.realtime_problem)
            self.journal.add(EventKind.HOST, "service", self.realtime_problem, realtime=False)
        self.bus_warnings = startup_link_problems(self.config.bus)
        for problem in self.bus_warnings:
            self.journal.add(EventKind.BUS, "service", problem)
        for run in self.recipe.unfinished():  # the runs a crash, a kill or a reboot left unfinished: offered, never run
            self.journal.add(EventKind.SERVICE, "service", f"unfinished run {run.run_id} ({run.recipe}, step "
                             f"{min(run.step, run.steps)}/{run.steps}): {run.reason}; `millctl recipe resume "
                             f"{run.run_id}` continues it after a pre-flight, `millctl recipe abort {run.run_id}` "
                             "closes it", run_id=run.run_id, record=str(run.path))
        self._thread.start()

    def wait_for_node(self, timeout_s: float) -> bool:
        """Wait until the controller has seen the node (left DISCONNECTED); False after ``timeout_s``."""
        return self._wait(lambda: self.controller.state is not S.DISCONNECTED or not self.running, timeout_s)

    def _loop(self) -> None:
        period_s = self.config.timing.controller_tick_s
        next_s = scheduled_s = time.monotonic()
        while not self._halt.is_set():
            started_s = time.monotonic()
            try:
                self.tick()
                self._run_commands()
                self.host.tick(started_s, started_s - scheduled_s, self.controller)  # lateness: started − scheduled
            except Exception as exc:  # the loop must say why it died; the node's watchdog does the rest
                log.exception("control loop failed")
                self.failed = f"control loop failed: {type(exc).__name__}: {exc}"
                self.journal.add(EventKind.SERVICE, "service", f"{self.failed}; heartbeat stopped, "
                                 "the node's watchdog stops the mill")
                return
            next_s += period_s
            scheduled_s = next_s  # kept for the lateness when a stall resets the schedule below
            delay_s = next_s - time.monotonic()
            if delay_s < -10.0 * period_s:  # far behind (a stall): do not try to catch up in a burst
                next_s = time.monotonic()
            self._halt.wait(max(delay_s, 0.0))

    def tick(self) -> None:
        """One step of everything, under the lock: controller, recipe runner, then the embedded node.

        The controller goes first: in one process a stall (the machine busy, a
        long request holding the lock) freezes controller and node alike, and
        the node must judge a heartbeat the controller had the chance to send,
        not the gap that both slept through. (A node in its own process, as on
        real hardware, keeps its own clock and watchdog: there a stalled
        controller trips it, as the hil tier shows.)
        """
        with self.lock:
            self.controller.tick()
            self.recipe.tick()
            if self.node is not None:
                self.node.tick()

    def _run_commands(self) -> None:
        """Run the commands waiting (STOPs and E-stops first), then publish the snapshot reads are answered from."""
        self.paths.run()

    def _take_snapshot(self) -> Snapshot:
        """What status reads are answered from (on the loop, under the lock)."""
        return finite(self.controller.status().as_dict()), self.recipe.recipe_out()

    def _execute(self, action: Callable[[Controller], T], needs_node: bool) -> T:
        if needs_node and self.controller.state is S.DISCONNECTED:
            raise NodeUnreachable(
                f"no NodeStatus from the node on {self.config.bus.interface}:{self.config.bus.channel} yet: "
                "is the node running and on the same bus?"
            )
        return action(self.controller)

    @property
    def running(self) -> bool:
        """True while the control loop runs."""
        return self._thread.is_alive() and self.failed is None

    def call(
        self, action: Callable[[Controller], T], *, needs_node: bool = True, timeout_s: float = COMMAND_TIMEOUT_S,
    ) -> T:
        """Have the control loop run ``action(controller)`` after its next tick and return the result.

        Refused at once when the loop is down, the node never answered, or the
        queue is full (STOP and E-stop: :meth:`call_urgent`). The
        loop thread itself (and a runtime whose loop never started) runs it here.
        """
        return self.paths.call(action, needs_node=needs_node, timeout_s=timeout_s)

    async def call_urgent(
        self, action: Callable[[Controller], T], *, needs_node: bool = False, stops: str | None = None,
        timeout_s: float = COMMAND_TIMEOUT_S,
    ) -> T:
        """Have the loop run ``action(controller)`` (a STOP, an E-stop) first at its next tick; never refused busy.

        ``stops`` (who stops) refuses every command waiting behind it: stop wins over start.
        """
        return await self.paths.call_urgent(action, needs_node=needs_node, stops=stops, timeout_s=timeout_s)

    def call_soon(self, action: Callable[[Controller], Any]) -> None:
        """Queue ``action(controller)`` for the loop without waiting (from the records thread; never raises)."""
        self.paths.call_soon(action)

    def status(self, timeout_s: float = COMMAND_TIMEOUT_S) -> dict[str, Any]:
        """The controller's status, JSON-ready (non-finite floats as None), from the loop's snapshot."""
        return self.paths.snapshot(timeout_s)[0]

    def recipe_view(self, timeout_s: float = COMMAND_TIMEOUT_S) -> RecipeOut:
        """The current (or last) recipe run's progress (``GET /v1/recipe``), from the loop's snapshot."""
        return self.paths.snapshot(timeout_s)[1]

    def describe(self) -> ServiceOut:
        """Which mill this service controls, and how (``GET /v1/service``)."""
        env = self.controller.envelope
        return ServiceOut(
            mill_name=self.config.name, simulated=self.node is not None, pid=os.getpid(), version=__version__,
            fault_injection=self.fault_injection,
            started_unix=self.started_unix, config_path=self.loaded.source, config_sha256=self.loaded.sha256,
            law=env.law.value, margin=env.margin, bus_interface=self.config.bus.interface,
            bus_channel=self.config.bus.channel, embedded_node=self.node is not None, socket_path=self.socket_path,
            records_dir=str(self.records_dir), bus_log=str(self.bus_log_path), warnings=self.warnings(),
            unfinished_runs=[run.run_id for run in self.recipe.unfinished()],
        )

    def warnings(self) -> list[str]:
        """What the operator must know about the service: its CAN link, records not written, interrupted runs."""
        found = [f"run {run.run_id} ({run.recipe}) is unfinished at step {min(run.step, run.steps)}/{run.steps}: "
                 f"{run.reason}; `millctl recipe resume {run.run_id}` continues it"
                 for run in self.recipe.unfinished()]
        if self.host.starvation is not None:  # a trip the host caused, until it is reset (SAFETY 27)
            found.append(self.host.starvation)
        if self.records_warning is None:
            return [*self.bus_warnings, *found]
        return [*self.bus_warnings,
                f"records cannot be written: {self.records_warning} ({self.records.lost} records lost so far; "
                f"records dir {self.records_dir}); the mill is controlled as before", *found]

    def _records_changed(self, failing: str | None) -> None:
        """On the records thread: writes started failing (or work again). Warn, record, stop a recipe."""
        self.records_warning = failing
        if failing is None:
            self.journal.add(EventKind.RECORDS, "service", f"records are written again ({self.records.lost} lost)",
                             lost=self.records.lost)
            return
        self.journal.add(EventKind.RECORDS, "service", f"records cannot be written: {failing}; the mill is "
                         "controlled as before, a running recipe is stopped", error=failing)

        def stop_recipe(c: Controller) -> None:
            self.recipe.abort_if_active("service", reason=f"records cannot be written ({failing})")

        self.call_soon(stop_recipe)

    # ------------------------------------------------------------------ shutdown
    def _at_rest(self) -> bool:
        with self.lock:
            state = self.controller.state
            measured = self.controller.measured
        if not self.running:
            return True
        if state in (S.RUNNING, S.STOPPING):
            return False
        return measured is None or max(abs(measured.rotary_rpm), abs(measured.vibration_rpm)) <= STANDSTILL_RPM

    def _wait(self, done: Callable[[], bool], bound_s: float) -> bool:
        deadline = time.monotonic() + bound_s
        while time.monotonic() < deadline:
            if done():
                return True
            time.sleep(0.02)
        return done()

    def stop_bound_s(self) -> float:
        """How long a controlled stop from the present speeds should take, plus 2 s, within STOP_BOUND_S (s)."""
        drives = self.config.drives
        with self.lock:
            measured = self.controller.measured
        if measured is None:
            return STOP_BOUND_S[0]
        expected_s = (abs(measured.rotary_rpm) / drives.rotary.max_accel_rpm_s
                      + abs(measured.vibration_rpm) / drives.vibration.max_accel_rpm_s + 2.0)
        return min(max(expected_s, STOP_BOUND_S[0]), STOP_BOUND_S[1])

    def shutdown(self, reason: str = "service stopping", bound_s: float | None = None) -> None:
        """Controlled stop (abort the recipe, stop the drives, wait for standstill, disarm), then close everything."""
        self.stopping = True
        bound_s = self.stop_bound_s() if bound_s is None else bound_s
        if self.running:
            with self.lock:
                self.recipe.interrupt_if_active(reason)  # stopped with the mill, resumable after the restart
                if self.controller.state in (S.ARMED, S.RUNNING, S.STOPPING):
                    self.controller.stop(source="service", reason=reason)
            stopped = self._wait(self._at_rest, bound_s)
            with self.lock:
                if stopped and self.controller.state is S.ARMED:
                    self.controller.disarm(source="service")
            self._wait(lambda: self.controller.state is not S.ARMED, 1.0)
            with self.lock:
                self.journal.add(EventKind.HOST, "service", self.host.summary(), session=True,
                                 **self.host.lateness.as_dict())  # before "service stopped", the last event
                measured = self.controller.measured
                shown = "unknown" if measured is None else f"{measured.rotary_rpm:.1f}/{measured.vibration_rpm:.1f} rpm"
                self.journal.add(
                    EventKind.SERVICE,
                    "service",
                    f"service stopped: {reason}; state {self.controller.state}, measured {shown}"
                    + ("" if stopped else f" (no standstill within {bound_s:.0f} s)"),
                    standstill=stopped,
                )
        self.close()

    def close(self) -> None:
        """Stop the loop and release the buses and the records (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self._halt.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        with self.lock:
            self.controller.drives.close()  # the drives backend's own threads (CiA 402: its SDO worker)
            self.bus.shutdown()
            if self.furnace_bus is not None:
                self.furnace_bus.shutdown()
            if self.node is not None:
                self.node.close()  # its physics worker; the bus is ours
            if self._node_bus is not None:
                self._node_bus.shutdown()
            self.journal.close()
        self.recipe.close()
        self.records.close()


__all__ = [
    "BUS_LOG_STEM",
    "COMMAND_QUEUE_SIZE",
    "COMMAND_TIMEOUT_S",
    "EMBEDDED_NODE_WAIT_S",
    "STATUS_MAX_AGE_S",
    "STOP_BOUND_S",
    "NodeUnreachable",
    "ServiceBusy",
    "ServiceRuntime",
]

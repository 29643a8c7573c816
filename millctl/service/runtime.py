"""The service's runtime: one control-loop thread owning the controller, the embedded node and the recipe runner.

Every ``timing.controller_tick_s`` the loop ticks the node (when embedded),
the controller and the recipe runner, all under one lock; API handlers call
the controller only under that same lock (:meth:`ServiceRuntime.call`). If
the loop dies, the heartbeat stops and the node's watchdog stops the mill
(SAFETY 2): the service never keeps commanding without its loop.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import can

from millctl import __version__
from millctl.api import EventKind
from millctl.clock import Clock, MonotonicClock
from millctl.config.loader import LoadedConfig
from millctl.controller import STANDSTILL_RPM, Controller, ControllerState
from millctl.errors import BusError
from millctl.protocol import RotatingBusLog, open_bus
from millctl.service.journal import Journal, finite
from millctl.service.lease import DEFAULT_TTL_S, LeaseManager
from millctl.service.recipe import RecipeSlot
from millctl.service.tap import TappedBus

log = logging.getLogger(__name__)

T = TypeVar("T")
S = ControllerState

BUS_LOG_NAME = "bus.log"
"""The candump bus log, in ``<records_dir>/bus/``."""

EMBEDDED_NODE_WAIT_S = 10.0
"""With the embedded node, the API opens once the controller has seen it (or after this long, s)."""

STOP_BOUND_S = (5.0, 30.0)
"""A shutdown waits for standstill the expected ramp-down time plus 2 s, kept within these bounds (s)."""


class NodeUnreachable(BusError):
    """The controller has not heard from the node (or the control loop is down): nothing can be commanded."""


class ServiceRuntime:
    """Owns the bus, the controller, the optional embedded node, the lease, the journal and the loop thread."""

    def __init__(
        self,
        loaded: LoadedConfig,
        *,
        clock: Clock | None = None,
        embed_node: bool | None = None,
        lease_ttl_s: float = DEFAULT_TTL_S,
    ) -> None:
        self.loaded = loaded
        config = self.config = loaded.config
        service = config.service
        self.clock = clock or MonotonicClock()
        self.records_dir = Path(service.records_dir)
        self.started_unix = time.time()
        self.journal = Journal(self.records_dir, rotate_bytes=service.rotate_bytes, keep_files=service.keep_files)
        self.lock = threading.RLock()
        self.leases = LeaseManager(self.clock, lease_ttl_s)
        self.failed: str | None = None
        self.stopping = False
        bus_log = RotatingBusLog(self.records_dir / "bus" / BUS_LOG_NAME, service.rotate_bytes, service.keep_files)
        self.bus = TappedBus(open_bus(config.bus), bus_log)
        self.controller = Controller(config, self.bus, self.clock, listener=self.journal.on_event)
        self.node: Any = None
        self._node_bus: can.BusABC | None = None
        if config.bus.interface == "virtual" if embed_node is None else embed_node:
            from firmware_sim.node import Node

            self._node_bus = open_bus(config.bus)
            self.node = Node(config, self._node_bus, self.clock)
        self.recipe = RecipeSlot(self.controller, self.clock, self.records_dir, loaded.sha256)
        self._halt = threading.Event()
        self._closed = False
        self._thread = threading.Thread(target=self._loop, name="millctl-control-loop", daemon=True)

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
        self._thread.start()

    def wait_for_node(self, timeout_s: float) -> bool:
        """Wait until the controller has seen the node (left DISCONNECTED); False after ``timeout_s``."""
        return self._wait(lambda: self.controller.state is not S.DISCONNECTED or not self.running, timeout_s)

    def _loop(self) -> None:
        period_s = self.config.timing.controller_tick_s
        next_s = time.monotonic()
        while not self._halt.is_set():
            try:
                self.tick()
            except Exception as exc:  # the loop must say why it died; the node's watchdog does the rest
                log.exception("control loop failed")
                self.failed = f"control loop failed: {type(exc).__name__}: {exc}"
                self.journal.add(EventKind.SERVICE, "service", f"{self.failed}; heartbeat stopped, "
                                 "the node's watchdog stops the mill")
                return
            next_s += period_s
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

    @property
    def running(self) -> bool:
        """True while the control loop runs."""
        return self._thread.is_alive() and self.failed is None

    def call(self, action: Callable[[Controller], T], *, needs_node: bool = True) -> T:
        """Run ``action(controller)`` under the lock; refuse when the loop is down or the node never answered."""
        if not self.running:
            raise NodeUnreachable(self.failed or "the control loop is not running")
        with self.lock:
            if needs_node and self.controller.state is S.DISCONNECTED:
                raise NodeUnreachable(
                    f"no NodeStatus from the node on {self.config.bus.interface}:{self.config.bus.channel} yet: "
                    "is the node running and on the same bus?"
                )
            return action(self.controller)

    def status(self) -> dict[str, Any]:
        """The controller's status, JSON-ready (non-finite floats as None)."""
        with self.lock:
            data: dict[str, Any] = finite(self.controller.status().as_dict())
        return data

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
                self.recipe.abort_if_active("service")
                if self.controller.state in (S.ARMED, S.RUNNING, S.STOPPING):
                    self.controller.stop(source="service", reason=reason)
            stopped = self._wait(self._at_rest, bound_s)
            with self.lock:
                if stopped and self.controller.state is S.ARMED:
                    self.controller.disarm(source="service")
            self._wait(lambda: self.controller.state is not S.ARMED, 1.0)
            with self.lock:
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
            self.bus.shutdown()
            if self.node is not None:
                self.node.close()  # its physics worker; the bus is ours
            if self._node_bus is not None:
                self._node_bus.shutdown()
            self.journal.close()


__all__ = ["BUS_LOG_NAME", "EMBEDDED_NODE_WAIT_S", "STOP_BOUND_S", "NodeUnreachable", "ServiceRuntime"]

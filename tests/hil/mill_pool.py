"""One started mill shared by consecutive scenarios of a test module (issue 36, part 5: the tiers' time).

Starting the service and the node costs seconds of CPU on the host and tens of seconds in the
vcan VM (everything there runs ~9× slower), and most scenarios only need a mill at rest, DISABLED.
So the ``mill`` fixtures of tests/hil/test_scenarios.py and test_adversary.py take one from a
module's :class:`MillPool`:
the scenario runs on it, and at its teardown the mill is brought back to what a fresh start gives
and checked (:meth:`MillPool.reset`): injected faults cleared, a running mill stopped, a trip reset,
the heater off, disarmed, control released; then the controller DISABLED with no trip cause, the
node DISABLED with no fault, both drives at standstill, no furnace target and the heater off. A
mill that cannot be brought back, whose scenario failed, whose processes died, or whose VM time
scale has moved on, is torn down and the next scenario starts a fresh one: a failing test cannot
poison the next.

One mill lives at a time, and none while a test runs processes of its own (an idle mill's service
and node tick at a real-time policy and would take CPU from the processes under test); the module's
tests are ordered by transport, pooled scenarios first (``conftest.pytest_collection_modifyitems``),
so that consecutive scenarios can share.

What stays per scenario: a start-up scenario asks for a fresh mill (``fresh=True``), so it sees
the processes start; scenarios that kill or restart a process, or start the mill with other
arguments, keep their own (``scenario_support.mill_on``).

Not pooled: the CiA 402 scenarios (test_cia402_scenarios.py). On that backend a second ARM after a
DISARM trips the service ("rotary drive (node 2) left OPERATION ENABLED by itself (now READY TO
SWITCH ON)", reproduced on ``virtual`` with a fresh mill: arm, disarm, arm, set speeds), so a reset
by disarming would hand the next scenario a mill that fails for a reason of its own.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from millctl.errors import MillctlError
from millctl.protocol import DriveTelemetry, SimFaultCode
from tests.hil.probe import is_kind
from tests.hil.scenario_support import Mill, bound_scale, wait_for

if TYPE_CHECKING:
    from tests.hil.conftest import Spawner, Transport

log = logging.getLogger(__name__)

RESET_TIMEOUT_S = 30.0
"""How long (s, idle host; scaled like every wait) the mill may take to come back to rest and DISABLED."""
SCALE_DRIFT = 1.25
"""In the VM, a mill configured at a time scale more than this factor below the test's own is restarted."""
REST_TIME_CONSTANTS = 3.0
"""A mill is handed on once both speeds have read exactly 0, without a break, for this many of the slower
drive's time constants (plus two telemetry periods): whatever speed was left when they last read
otherwise has decayed to e⁻³ of it (:class:`RestWatch`)."""


OPEN_POOLS: list[MillPool] = []
"""The pools of the modules running now: a test that starts its own processes closes their idle mills first
(``conftest.spawn``), so that no idle mill's real-time processes compete with the ones under test."""


@dataclass(frozen=True)
class MillKind:
    """What a scenario needs of its mill: the transport, the drive backend, the drives' dilation (``write_config``)."""

    transport: str
    backend: str = "millbus"
    dilate_drives: bool = False


@dataclass
class _Entry:
    mill: Mill
    transport: Transport
    spawner: Spawner
    scale: float
    """``bound_scale()`` when the mill's config was written (1 on the host)."""
    scenarios: int = 0


class MillPool:
    """Started mills by :class:`MillKind`, handed to one scenario at a time (a module's fixture)."""

    def __init__(
        self, workdir: Path, make_transport: Callable[[str], Transport], make_spawner: Callable[[Path], Spawner]
    ) -> None:
        self._workdir = workdir
        self._make_transport = make_transport
        self._make_spawner = make_spawner
        self._entries: dict[MillKind, _Entry] = {}
        self._started = 0
        self.leaked: list[str] = []
        """Processes a torn-down mill left running (the module's teardown fails on them)."""
        self.restarts: list[str] = []
        """Why a mill was torn down before the next scenario (printed at the module's end)."""

    def get(self, kind: MillKind, *, fresh: bool = False) -> Mill:
        """A started mill of ``kind``, DISABLED at rest; ``fresh``: newly started (the start-up scenarios)."""
        for other in [k for k in self._entries if k != kind]:  # one live mill at a time: an idle one takes CPU
            self._discard(other, None)
        entry = self._entries.get(kind)
        if entry is not None:
            reason = "a fresh start asked for" if fresh else self._unusable(entry)
            if reason is not None:
                self._discard(kind, reason)
                entry = None
        if entry is None:
            entry = self._start(kind)
        entry.scenarios += 1
        if entry.mill.probe is not None:
            entry.mill.probe.forget()  # the scenario sees the frames of its own time only, as on a new probe
        return entry.mill

    def give_back(self, kind: MillKind, *, failed: bool) -> None:
        """After the scenario: bring the mill back to rest and DISABLED, or tear it down (failed, or not back)."""
        entry = self._entries.get(kind)
        if entry is None:
            return
        if failed:
            self._discard(kind, "its scenario failed")
            return
        try:
            self.reset(entry.mill)
        except (Exception, pytest.fail.Exception) as exc:  # wait_for's timeout is pytest.fail's (a BaseException)
            self._discard(kind, f"not back at rest and DISABLED: {type(exc).__name__}: {exc}")

    def close(self) -> None:
        """Tear every mill down; their leftovers go to :attr:`leaked`."""
        for kind in list(self._entries):
            self._discard(kind, None)

    def __enter__(self) -> MillPool:
        OPEN_POOLS.append(self)
        return self

    def __exit__(self, *exc: object) -> None:
        OPEN_POOLS.remove(self)
        self.close()

    # -- the known state
    @staticmethod
    def reset(mill: Mill) -> None:
        """Clear injected faults, stop, reset a trip, disarm, release; raise unless the mill is as a fresh start."""
        if mill.service is None or mill.service.poll() is not None:
            raise AssertionError("the service is not running")
        if mill.node is not None and mill.node.poll() is not None:
            raise AssertionError("the node is not running")
        if mill.probe is not None:
            mill.probe.inject(SimFaultCode.CLEAR)
        client = mill.client
        client.take_control()
        state = mill.status()["state"]
        if state in ("RUNNING", "STOPPING", "RAMPING"):
            client.stop()
        _wait(mill, mill.at_standstill, "both drives at standstill")
        _wait(mill, lambda: mill.status()["state"] not in ("RUNNING", "STOPPING", "RAMPING"), "the stop to end")
        if mill.status()["state"] == "TRIPPED":
            _wait(mill, lambda: _reset_taken(mill), "the trip to be reset (at standstill)")
        if mill.status()["furnace_target_c"] is not None:
            client.set_furnace(None)
        if mill.status()["state"] == "ARMED":
            client.disarm()
        _wait(mill, lambda: _as_fresh(mill.status()), "the controller and the node DISABLED with no fault at rest")
        rest = RestWatch(mill)
        _wait(mill, rest, f"both speeds to read exactly 0 for {rest.window_s:.2f} s")
        client.release_control()
        status = mill.status()
        problem = _as_fresh(status)
        assert problem is True, f"after the reset: {status}"

    # -- the entries
    def _unusable(self, entry: _Entry) -> str | None:
        mill = entry.mill
        for name, proc in (("service", mill.service), ("node", mill.node)):
            if proc is not None and proc.poll() is not None:
                return f"its {name} exited ({proc.returncode})"
        if bound_scale() > entry.scale * SCALE_DRIFT:
            return f"the time scale moved from {entry.scale:.2f} to {bound_scale():.2f}: its config is sized for less"
        return None

    def _start(self, kind: MillKind) -> _Entry:
        self._started += 1
        directory = self._workdir / f"mill{self._started}"
        directory.mkdir()
        transport = self._make_transport(kind.transport)
        spawner = self._make_spawner(directory)
        mill = Mill(transport, spawner, directory, dilate_drives=kind.dilate_drives, backend=kind.backend)
        entry = _Entry(mill, transport, spawner, bound_scale())
        self._entries[kind] = entry
        mill.start()
        return entry

    def _discard(self, kind: MillKind, reason: str | None) -> None:
        entry = self._entries.pop(kind)
        if reason is not None:
            note = f"{kind}: restarted after {entry.scenarios} scenario(s): {reason}"
            self.restarts.append(note)
            log.warning("mill pool: %s", note)
        try:
            entry.mill.close()
        finally:
            self.leaked += entry.spawner.cleanup()
            entry.transport.close()


def _wait(mill: Mill, condition: Callable[[], Any], what: str) -> None:
    wait_for(lambda: condition() or None, mill.timeout(RESET_TIMEOUT_S), what)


def _reset_taken(mill: Mill) -> bool:
    """Ask for a reset when both drives are at rest; True once the controller has left TRIPPED.

    The controller refuses a reset while a drive still reads above its standstill threshold (a coasting
    drive, sensor noise around it): asked again on the next poll, as an operator would.
    """
    if mill.status()["state"] != "TRIPPED":
        return True
    if mill.at_standstill():
        try:
            mill.client.reset()
        except MillctlError as exc:
            log.info("mill pool: reset refused, asking again: %s", exc)
    return bool(mill.status()["state"] != "TRIPPED")


def _as_fresh(status: dict[str, Any]) -> bool | None:
    """True when ``status`` is what a freshly started mill reports (None otherwise: the wait goes on).

    Both speeds reading exactly 0 is necessary, not sufficient: a simulated encoder reads 0 at rest
    and ``max(0, ω + noise)`` while turning (firmware_sim/drives.py, noise σ up to 1 rpm), so a drive
    still coasting at 0.5 rpm reads 0 one time in three. :class:`RestWatch` waits for the rest.
    """
    fresh = (
        status["state"] == "DISABLED"
        and status["node_state"] == "DISABLED"
        and not status["trip_cause"]
        and not status["node_faults"]
        and status["furnace_target_c"] is None
        and not status["heater_on"]
        and float(status["measured_rotary_rpm"]) == 0.0
        and float(status["measured_vibration_rpm"]) == 0.0
    )
    return True if fresh else None


class RestWatch:
    """A wait condition: True once both drives have read exactly 0, without a break, for :attr:`window_s`.

    The node ends a controlled stop, and accepts DISARM, once the drives are within the measurement
    tolerance of rest (firmware_sim/node.py ``_at_rest``), so a mill can be DISABLED with a drive still
    coasting, and its encoder's noise (clamped at 0) reads 0 often enough to pass one look. A drive
    coasting at 0.5 rpm handed on so read 1.8 rpm in the next scenario
    (test_scenarios.py::test_over_limit_setpoint_refused_by_the_controller, in CI and under two CPU
    hogs). With a probe the window is judged from every DriveTelemetry frame it captured since the
    scenario began (no wait at all when the drives never moved); without one, from the status polls.
    """

    def __init__(self, mill: Mill) -> None:
        self.mill = mill
        drives = mill.config.drives
        slowest_s = max(drives.rotary.time_constant_s, drives.vibration.time_constant_s)
        period_s = mill.codec.cycle_time_s(DriveTelemetry)
        assert period_s is not None, "DriveTelemetry has no cycle time in the DBC"
        self.window_s = REST_TIME_CONSTANTS * slowest_s + mill.bounds.scaled(2.0 * period_s)
        self._zero_since: float | None = None

    def __call__(self) -> bool:
        probe = self.mill.probe
        if probe is not None:
            frames = probe.frames(where=is_kind(DriveTelemetry))
            moving = [s.t for s in frames if _speeds(s.of(DriveTelemetry)) != (0.0, 0.0)]
            if not frames or (moving and moving[-1] == frames[-1].t):
                return False
            return not moving or bool(probe.now() - moving[-1] >= self.window_s)
        status = self.mill.status()
        now = time.monotonic()
        if (float(status["measured_rotary_rpm"]), float(status["measured_vibration_rpm"])) != (0.0, 0.0):
            self._zero_since = None
            return False
        if self._zero_since is None:
            self._zero_since = now
        return now - self._zero_since >= self.window_s


def _speeds(telemetry: DriveTelemetry) -> tuple[float, float]:
    return float(telemetry.rotary_rpm), float(telemetry.vibration_rpm)


__all__ = ["MillKind", "MillPool", "RestWatch"]

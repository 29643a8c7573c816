"""Know the host (SAFETY 27, issue 37 item 7): the loop's lateness, its warnings, host-starvation trips, sd_notify.

The trip case runs the real node and the real controller in the in-process
rig, the node ticking as a process of its own would while the controller's
loop is held back (a starved host): the node's watchdog stops the mill, the
controller trips on the node's WATCHDOG fault, and the watch names the trip
as host starvation with the figures. A trip of the mill's own (a stalled
vibration drive) right after a late tick is not laid at the host's door.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from millctl.api import EventKind
from millctl.config import MillConfig, load_config
from millctl.controller import ControllerState as S
from millctl.looptime import LoopLateness
from millctl.protocol import SimFaultCode
from millctl.service import ServiceRuntime
from millctl.service.host import HostWatch, realtime_policy_problem
from millctl.service.sdnotify import Notifier
from tests.support.pace import stretched
from tests.support.service import write_config
from tests.unit.scenarios.rig import Rig


class Recorded:
    """A journal's ``add`` that keeps what it was given."""

    def __init__(self) -> None:
        self.events: list[tuple[str, str, dict[str, Any]]] = []

    def __call__(self, kind: str, source: str, message: str, **data: Any) -> dict[str, Any]:
        self.events.append((kind, message, data))
        return {}

    def of(self, kind: EventKind) -> list[tuple[str, str, dict[str, Any]]]:
        return [event for event in self.events if event[0] == kind]


@pytest.fixture
def rig(config: MillConfig) -> Iterator[Rig]:
    """The real node and controller in one process (tests/unit/scenarios/rig.py)."""
    r = Rig(config)
    yield r
    r.close()


def test_loop_lateness_keeps_the_last_mean_maximum_and_the_recent_window() -> None:
    figures = LoopLateness(0.25, window_s=1.0)
    assert figures.warn_s == 0.125
    assert figures.record(0.0, 0.002) is None
    late = figures.record(0.01, 0.3)
    assert late is not None and late.lateness_s == 0.3 and figures.late_ticks == 1
    for k in range(1, 200):
        figures.record(0.01 + 0.01 * k, 0.001)
    assert figures.max_s == 0.3 and figures.last_s == 0.001
    assert figures.recent_max_s == 0.001  # the late tick is more than the window ago
    assert figures.late_within(2.0, 1.0) is None and figures.late_within(1.0, 1.0) is late
    assert figures.as_dict()["max_ms"] == 300.0 and figures.ticks == 201
    assert figures.record(3.0, -0.5) is None and figures.last_s == 0.0  # early is on time
    with pytest.raises(ValueError, match="watchdog bound"):
        LoopLateness(0.0)


def starve(rig: Rig, watch: HostWatch, seconds: float) -> float:
    """Tick the node alone for ``seconds`` (the controller's loop starved), then resume both; the lateness (s)."""
    started = rig.clock.now()
    for _ in range(round(seconds / rig.dt_s)):
        rig.node.tick()
        rig.clock.advance(rig.dt_s)
    lateness_s = rig.clock.now() - started
    for k in range(round(2.0 / rig.dt_s)):
        rig.step()
        watch.tick(rig.clock.now(), lateness_s if k == 0 else 0.001, rig.controller)
    return lateness_s


def test_a_trip_after_a_late_loop_is_named_host_starvation_with_the_figures(config: MillConfig, rig: Rig) -> None:
    recorded = Recorded()
    watch = HostWatch(config, recorded, Notifier(path=""))
    rig.start(30.0, 150.0)
    lateness_s = starve(rig, watch, 0.6)
    assert rig.controller.state is S.TRIPPED and "WATCHDOG" in rig.controller.trip_cause
    named = [message for _, message, data in recorded.of(EventKind.HOST) if data.get("host_starvation")]
    expected = (
        f"the control loop ran {lateness_s * 1e3:.0f} ms late; the node's watchdog allows 250 ms: the host is "
        "overloaded, see docs/deployment.md#real-time-priority"
    )
    assert named == [f"trip caused by host starvation: {expected}"], recorded.events
    assert watch.starvation == named[0]
    warned = [data for _, _, data in recorded.of(EventKind.HOST) if "late_ticks" in data]
    assert len(warned) == 1 and warned[0]["max_ms"] == pytest.approx(lateness_s * 1e3, abs=0.01)


def test_a_trip_of_the_mill_s_own_is_not_laid_at_the_host_s_door(config: MillConfig, rig: Rig) -> None:
    recorded = Recorded()
    watch = HostWatch(config, recorded, Notifier(path=""))
    rig.start(30.0, 150.0)
    watch.tick(rig.clock.now(), 0.2, rig.controller)  # late, but not past the node's watchdog
    rig.inject(SimFaultCode.VIB_STALL)
    for _ in range(round(5.0 / rig.dt_s)):
        rig.step()
        watch.tick(rig.clock.now(), 0.001, rig.controller)
        if rig.controller.state is S.TRIPPED:
            break
    assert rig.controller.state is S.TRIPPED and "WATCHDOG" not in rig.controller.trip_cause
    assert watch.starvation is None
    assert [data for _, _, data in recorded.of(EventKind.HOST) if data.get("host_starvation")] == []
    assert len(recorded.of(EventKind.HOST)) == 1  # the late tick's warning, nothing more


def test_warnings_are_rate_limited_and_count_the_late_ticks_between(config: MillConfig, rig: Rig) -> None:
    recorded = Recorded()
    watch = HostWatch(config, recorded, Notifier(path=""))
    for k in range(10):
        watch.tick(0.5 * k, 0.2, rig.controller)  # late every half second for 5 s
    watch.tick(5.0, 0.2, rig.controller)
    warned = recorded.of(EventKind.HOST)
    assert [data["late_ticks"] for _, _, data in warned] == [1, 10]
    assert "ran 200 ms late" in warned[0][1] and "docs/deployment.md#real-time-priority" in warned[0][1]


@pytest.fixture
def notify_socket(tmp_path: Path) -> Iterator[tuple[socket.socket, str]]:
    """A fake systemd notify socket (an AF_UNIX datagram socket, as systemd's NOTIFY_SOCKET)."""
    path = str(tmp_path / "notify")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(path)
    sock.settimeout(stretched(5.0))
    try:
        yield sock, path
    finally:
        sock.close()


def test_sd_notify_sends_ready_and_watchdog_pings_at_half_the_interval(
    notify_socket: tuple[socket.socket, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    sock, path = notify_socket
    monkeypatch.setenv("NOTIFY_SOCKET", path)
    monkeypatch.setenv("WATCHDOG_USEC", "2000000")
    notifier = Notifier()
    assert notifier.enabled and notifier.watchdog_s == 2.0
    assert notifier.ready("serving /run/millctl/mill.sock")
    assert sock.recv(256) == b"READY=1\nSTATUS=serving /run/millctl/mill.sock"
    assert notifier.ping(100.0)
    assert sock.recv(64) == b"WATCHDOG=1"
    assert not notifier.ping(100.9)  # within half the interval: nothing sent
    assert notifier.ping(101.0)
    assert sock.recv(64) == b"WATCHDOG=1"


def test_sd_notify_does_nothing_outside_systemd_and_survives_a_gone_socket(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("NOTIFY_SOCKET", raising=False)
    monkeypatch.delenv("WATCHDOG_USEC", raising=False)
    assert not Notifier().ready() and not Notifier().ping(0.0)
    gone = Notifier(path=str(tmp_path / "no-such-socket"), watchdog_usec="1000000")
    assert not gone.ping(0.0) and gone.failures == 1


def test_the_service_loop_measures_its_lateness_warns_and_pings_systemd(
    tmp_path: Path, notify_socket: tuple[socket.socket, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The real runtime's loop, one tick held back 0.3 s (a starved host): a host event with the figures, and
    WATCHDOG=1 from the loop; without a real-time policy, the start says so."""
    sock, path = notify_socket
    monkeypatch.setenv("NOTIFY_SOCKET", path)
    monkeypatch.setenv("WATCHDOG_USEC", "1000000")
    runtime = ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False)
    runtime.host.notifier = Notifier()
    tick = runtime.tick
    held: list[bool] = []

    def slow_once() -> None:
        if not held:
            held.append(True)
            time.sleep(0.3)
        tick()

    monkeypatch.setattr(runtime, "tick", slow_once)
    runtime.start()
    try:
        assert sock.recv(64) == b"WATCHDOG=1"
        deadline = time.monotonic() + stretched(10.0)
        while time.monotonic() < deadline and runtime.host.lateness.late_ticks == 0:
            time.sleep(0.02)
        assert runtime.host.lateness.late_ticks >= 1 and runtime.host.lateness.max_s >= 0.29
        assert runtime.host.lateness.ticks > 1
    finally:
        runtime.close()
    events = [e for e in runtime.journal.after(0) if e["kind"] == EventKind.HOST]
    assert any("the control loop ran" in e["message"] and e["data"]["max_ms"] >= 290.0 for e in events), events
    if realtime_policy_problem() is not None:
        assert runtime.realtime_problem is not None
        assert any("not a real-time one" in e["message"] for e in events)
        assert runtime.realtime_problem not in runtime.warnings()  # said at start, not a standing warning

"""Fixtures of the hil tier: one test, run over every transport, with its processes cleaned up.

``transport`` is parametrised over python-can's ``virtual`` bus (in-process),
``udp_multicast`` (between processes, only inside a private network namespace:
run the tier through ``tests/hil/in_netns``) and ``socketcan`` on vcan0 (only
where vcan0 exists: in the VM of ``tests/vm/run``, or a host that has it).
``spawn`` starts helper processes (the node, the controller, a rogue sender)
and kills and reaps them at teardown, failing the test if any was left running.

Waits for processes (``Transport.timeout``, the spawner's grace periods) are
sized for an idle host and stretched by ``tests.support.pace``: times
``MILLCTL_TIME_SCALE`` (the VM's emulation slowdown, measured by ``tests/vm/run``)
and by the load measured when the wait starts. Physical bounds are not waits:
see ``scenario_support.Bounds``.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import can
import pytest

from tests.support.pace import cpu_share, scale_for_a_test, stretched, time_scale
from tests.support.realtime import Role
from tests.support.realtime import describe as describe_realtime
from tests.support.realtime import popen as realtime_popen

if TYPE_CHECKING:
    from tests.hil.mill_pool import MillKind, MillPool
    from tests.hil.scenario_support import Mill

REPO = Path(__file__).resolve().parents[2]
IN_VM = os.environ.get("MILLCTL_IN_VM") == "1"
VCAN = "vcan0"
# An administratively scoped IPv4 group; the netns routes 224.0.0.0/4 to lo.
MULTICAST_GROUP = "239.74.163.2"


def pytest_report_header() -> str:
    """Which scheduling policy the service and node run at (real-time under .ci/test, where permitted)."""
    return describe_realtime()


# --- where each transport can run -------------------------------------------


def _interfaces() -> list[str]:
    """Network interfaces of *this* network namespace (sysfs may show the parent's)."""
    return sorted(name for _, name in socket.if_nameindex())


def _has_multicast_route_on_lo() -> bool:
    """Whether 224.0.0.0/4 is routed to lo (``/proc/net/route`` is per namespace)."""
    lines = Path("/proc/net/route").read_text().splitlines()[1:]
    return any(f.split()[:2] == ["lo", "000000E0"] and f.split()[7] == "000000F0" for f in lines)


def udp_multicast_unavailable() -> str | None:
    """Why udp_multicast must not run here, or None inside a private namespace.

    Multicast is sent only where lo is the sole interface, so no frame can
    leave the machine; the check never opens a socket.
    """
    names = _interfaces()
    if names != ["lo"]:
        return (
            f"udp_multicast runs only in a private network namespace (this one has {', '.join(names)}); "
            "run the tier as: tests/hil/in_netns .venv/bin/python -m pytest tests/hil"
        )
    if not _has_multicast_route_on_lo():
        return "no 224.0.0.0/4 route on lo in this namespace; run the tier through tests/hil/in_netns"
    return None


def socketcan_unavailable() -> str | None:
    """Why socketcan on vcan0 cannot run here, or None where vcan0 exists."""
    if VCAN in _interfaces():
        return None
    return f"no {VCAN} in this network namespace (the vcan tier runs in a VM: tests/vm/run)"


# --- the transport fixture --------------------------------------------------


@dataclass
class Transport:
    """One way of carrying CAN frames, as a test sees it.

    ``bus_kwargs`` are the keyword arguments of ``can.Bus`` for this transport
    (JSON-serialisable, so they can be handed to a subprocess); every bus
    opened through :meth:`open_bus` is shut down at teardown.
    """

    name: str
    bus_kwargs: dict[str, Any]
    crosses_processes: bool
    """False for ``virtual``: its frames stay inside one Python process."""
    echoes_own_frames: bool
    """True for ``udp_multicast``: a bus receives the frames it sent itself."""
    time_scale: float = 1.0
    _buses: list[can.BusABC] = field(default_factory=list, repr=False)

    def open_bus(self, **overrides: Any) -> can.BusABC:
        """Open a ``can.Bus`` on this transport (closed at teardown).

        This is plain python-can on purpose, so the smoke tests do not depend
        on millctl.protocol. Scenario tests that need the project's bus
        factory (e.g. the echo-dropping ``millctl_udp_multicast`` interface)
        should build it from :meth:`bus_config_fields` instead.
        """
        bus = can.Bus(**{**self.bus_kwargs, **overrides})
        self._buses.append(bus)
        return bus

    def bus_config_fields(self) -> dict[str, Any]:
        """The ``[bus]`` fields of a millctl config for this transport (interface, channel, options)."""
        options = {k: v for k, v in self.bus_kwargs.items() if k not in ("interface", "channel")}
        return {"interface": self.bus_kwargs["interface"], "channel": self.bus_kwargs["channel"], "options": options}

    def bus_kwargs_json(self) -> str:
        """``bus_kwargs`` as JSON, for a subprocess's command line or environment."""
        return json.dumps(self.bus_kwargs)

    def timeout(self, seconds: float) -> float:
        """A wait of ``seconds`` on an idle host, scaled for the VM and stretched by the load now (support.pace)."""
        return seconds * self.time_scale / cpu_share()

    def close(self) -> None:
        """Shut down every bus opened through this transport."""
        while self._buses:
            self._buses.pop().shutdown()


def _free_udp_port() -> int:
    """A UDP port nobody uses right now (a fresh one for each test)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def _make_transport(name: str) -> Transport:
    """Build the transport ``name`` for one test, or skip (or fail) where it cannot run."""
    scale = time_scale()
    if name == "virtual":
        # A channel of its own, so tests never hear each other.
        kwargs: dict[str, Any] = {"interface": "virtual", "channel": f"hil-{uuid.uuid4().hex[:8]}"}
        return Transport(name, kwargs, crosses_processes=False, echoes_own_frames=False, time_scale=scale)
    if name == "udp_multicast":
        if reason := udp_multicast_unavailable():
            pytest.skip(reason)
        kwargs = {
            "interface": "udp_multicast",
            "channel": MULTICAST_GROUP,
            "port": _free_udp_port(),
            "hop_limit": 0,  # TTL 0: never forwarded off this host (and this netns has only lo)
        }
        return Transport(name, kwargs, crosses_processes=True, echoes_own_frames=True, time_scale=scale)
    if name == "socketcan":
        if reason := socketcan_unavailable():
            if IN_VM:
                pytest.fail(f"MILLCTL_IN_VM=1 but {reason}: tests/vm/run must create {VCAN} before pytest")
            pytest.skip(reason)
        kwargs = {"interface": "socketcan", "channel": VCAN}
        return Transport(name, kwargs, crosses_processes=True, echoes_own_frames=False, time_scale=scale)
    raise ValueError(f"unknown transport {name!r}")


TRANSPORTS = ("virtual", "udp_multicast", "socketcan")
RUN_TIME_SCALE = time_scale()
"""The run's time scale (``MILLCTL_TIME_SCALE`` as pytest started: in the VM, measured as it booted)."""


@pytest.fixture(autouse=True)
def per_test_time_scale(monkeypatch: pytest.MonkeyPatch) -> float:
    """This test's time scale: in the VM measured again as the test starts (``pace.scale_for_a_test``).

    Autouse, so it runs before the transport, the spawner and the mill read ``time_scale()``: the
    test's waits, the VM's config periods and the bounds all follow the VM's speed at this moment,
    not at boot. On the host (and with a forced scale) it is the run's figure, unchanged.
    """
    scale = scale_for_a_test(RUN_TIME_SCALE)
    if scale != RUN_TIME_SCALE:
        monkeypatch.setenv("MILLCTL_TIME_SCALE", f"{scale:.2f}")
    return time_scale()


@pytest.fixture(params=TRANSPORTS)
def transport(request: pytest.FixtureRequest) -> Iterator[Transport]:
    """The transport under test; its buses are shut down at teardown."""
    t = _make_transport(request.param)
    try:
        yield t
    finally:
        t.close()


# --- processes --------------------------------------------------------------


class Spawner:
    """Starts helper processes and guarantees they are gone after the test.

    Each child runs in a session of its own, so teardown can signal its whole
    process group (grandchildren included). Output goes to files in the
    test's tmp_path; read it with :meth:`output`.
    """

    def __init__(self, workdir: Path, scale: float) -> None:
        self._workdir = workdir
        self.scale = scale
        self._procs: list[subprocess.Popen[bytes]] = []
        self._logs: dict[int, Path] = {}

    def __call__(
        self, argv: list[str], *, env: dict[str, str] | None = None, realtime: Role | None = None
    ) -> subprocess.Popen[bytes]:
        """Start ``argv`` (``python`` as the first item means this interpreter) in the repo root.

        stdout and stderr go to one log file; ``env`` is added to this process's environment.
        ``realtime``: at that role's real-time policy, if pytest was started with one (the node,
        and the controller service below it, whose timing the tests check: ``tests.support.realtime``).
        """
        if argv and argv[0] == "python":
            argv = [sys.executable, *argv[1:]]
        log = self._workdir / f"proc{len(self._procs)}.log"
        with log.open("wb") as out:
            proc = realtime_popen(
                argv,
                realtime=realtime,
                cwd=REPO,
                env={**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})},  # a failure shows all they printed
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        self._procs.append(proc)
        self._logs[proc.pid] = log
        return proc

    def output(self, proc: subprocess.Popen[bytes]) -> str:
        """Everything ``proc`` wrote to stdout and stderr so far."""
        return self._logs[proc.pid].read_text(errors="replace")

    def stop(self, proc: subprocess.Popen[bytes], sig: int = signal.SIGTERM, grace_s: float = 5.0) -> int:
        """Send ``sig`` to ``proc``'s process group, SIGKILL after ``grace_s`` (stretched); return its exit code.

        The grace covers the whole group: helpers the child started
        (multiprocessing workers, its resource tracker) get it too.
        """
        _signal_group(proc.pid, sig)
        grace_s = stretched(grace_s)
        deadline = time.monotonic() + grace_s
        try:
            rc = proc.wait(grace_s)
        except subprocess.TimeoutExpired:
            _signal_group(proc.pid, signal.SIGKILL)
            rc = proc.wait()
        if _wait_group_gone(proc.pid, deadline - time.monotonic()):
            _signal_group(proc.pid, signal.SIGKILL)
            _wait_group_gone(proc.pid, stretched(KILL_WAIT_S))
        return rc

    def cleanup(self) -> list[str]:
        """Kill and reap every child; return a description of each one that was still running.

        A child that exited may leave helpers that are exiting by themselves
        (a multiprocessing resource tracker notices its parent's exit a moment
        later): they get ``LINGER_S`` (scaled) before they count as leaked.
        """
        leaked = []
        for proc in self._procs:
            running = proc.poll() is None  # poll() reaps an exited leader, so only its group is left
            stragglers = [] if running else _wait_group_gone(proc.pid, stretched(LINGER_S))
            if running or stragglers:
                who = ", ".join(_describe(pid) for pid in stragglers) or "itself"
                leaked.append(
                    f"{proc.args!r} (pid {proc.pid}; left running: {who}); its output:\n{self.output(proc)[-2000:]}"
                )
            _signal_group(proc.pid, signal.SIGKILL)
            proc.wait()
            _wait_group_gone(proc.pid, stretched(KILL_WAIT_S))  # SIGKILL is delivered, not yet acted on
        return leaked


LINGER_S = 2.0  # how long an exited child's helpers may take to exit by themselves
KILL_WAIT_S = 5.0  # how long SIGKILLed processes may take to disappear


def _signal_group(pgid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError):  # the whole group has already exited
        os.killpg(pgid, sig)


def _live_group_members(pgid: int) -> list[int]:
    """PIDs in process group ``pgid`` that are not zombies.

    An orphaned grandchild is reaped by init, which may take its time (or, in
    some containers, never): a zombie is dead, so it does not count.
    """
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # exited while we looked
        state, pgrp = fields[0], int(fields[2])
        if pgrp == pgid and state not in ("Z", "X"):
            pids.append(int(stat.parent.name))
    return pids


def _wait_group_gone(pgid: int, timeout_s: float) -> list[int]:
    """Wait up to ``timeout_s`` for group ``pgid`` to have no live member; return those still alive."""
    deadline = time.monotonic() + timeout_s
    while (alive := _live_group_members(pgid)) and time.monotonic() < deadline:
        time.sleep(0.02)
    return alive


def _describe(pid: int) -> str:
    try:
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
    except OSError:
        cmdline = "?"
    return f"pid {pid} [{cmdline[:120]}]"


@pytest.fixture
def spawn(tmp_path: Path) -> Iterator[Spawner]:
    """``spawn(argv) -> Popen``; every child is killed and reaped at teardown.

    A child (or a grandchild in its process group) still running at teardown
    fails the test: a test stops what it starts (``spawn.stop(proc)``) or
    waits for it to exit.
    """
    from tests.hil.mill_pool import OPEN_POOLS

    for pool in OPEN_POOLS:  # no idle shared mill beside the processes this test starts
        pool.close()
    spawner = Spawner(tmp_path, time_scale())
    yield spawner
    leaked = spawner.cleanup()
    if leaked:
        pytest.fail("processes left running at teardown (killed now):\n" + "\n".join(leaked), pytrace=False)


# --- one mill for consecutive scenarios (tests/hil/mill_pool.py) ------------------------------------------------

FAILED = pytest.StashKey[bool]()
"""Set on a test item when any phase of it failed: its shared mill is torn down, not handed on."""


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Iterator[None]:
    """Note a failed setup or call on the item (read by :func:`pooled_mill` at its teardown)."""
    outcome = yield
    if outcome.get_result().failed:  # type: ignore[attr-defined]
        item.stash[FAILED] = True


@pytest.fixture(scope="module")
def mill_pool(tmp_path_factory: pytest.TempPathFactory) -> Iterator[MillPool]:
    """The module's started mills, one per kind; torn down at the module's end, failing on processes left running."""
    from tests.hil.mill_pool import MillPool

    with MillPool(tmp_path_factory.mktemp("pool"), _make_transport, lambda d: Spawner(d, time_scale())) as pool:
        yield pool
    for note in pool.restarts:
        print(f"mill pool: {note}")
    if pool.leaked:
        pytest.fail("processes left running at teardown (killed now):\n" + "\n".join(pool.leaked), pytrace=False)


@contextlib.contextmanager
def pooled_mill(
    request: pytest.FixtureRequest, pool: MillPool, kind: MillKind, *, fresh: bool = False
) -> Iterator[Mill]:
    """The pool's mill of ``kind`` for one test; handed back at its end (torn down if the test failed)."""
    mill = pool.get(kind, fresh=fresh)
    try:
        yield mill
    finally:
        pool.give_back(kind, failed=request.node.stash.get(FAILED, False))


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """In a module with pooled scenarios: by transport, pooled first, so consecutive ones share a mill.

    Otherwise file order; the order between modules is kept. Each test stays independent of the
    others (the pool resets or restarts the mill between them), so this changes time, not meaning.
    """
    def key(item: pytest.Item) -> tuple[int, int, int]:
        spec = getattr(item, "callspec", None)
        name = spec.params.get("transport") if spec is not None else None
        rank = TRANSPORTS.index(name) if name in TRANSPORTS else -1
        return rank, 0 if "mill_pool" in getattr(item, "fixturenames", ()) else 1, position[item]

    position = {item: i for i, item in enumerate(items)}
    start = 0
    while start < len(items):
        end = start
        while end < len(items) and items[end].module is items[start].module:  # type: ignore[attr-defined]
            end += 1
        if any("mill_pool" in getattr(item, "fixturenames", ()) for item in items[start:end]):
            items[start:end] = sorted(items[start:end], key=key)
        start = end

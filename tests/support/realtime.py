"""Real-time scheduling for the processes whose timing a hil test checks: the controller service and the node.

A mill controller runs its control loop under a real-time policy (SCHED_FIFO or
SCHED_RR, docs/deployment.md "Real-time priority"), so that other work on the
machine cannot delay a heartbeat or a trip. The hil tiers do the same for the
processes whose timing they assert (the 250 ms heartbeat watchdog, trips within
~0.1 s): ``.ci/test`` starts pytest under ``chrt --rr 20`` (``tests/hil/rt``), and only the service
and the node keep that policy; pytest itself, the probes, floods and clients run
at the normal policy, like any other job.

How the policy gets to the right processes: the udp_multicast cases run inside
an unprivileged user namespace (``tests/hil/in_netns``), where no process may
raise its own policy (CAP_SYS_NICE is the init namespace's, and RLIMIT_RTPRIO
cannot be raised without CAP_SYS_RESOURCE), but a policy set before entering it
is inherited through fork and exec. So :func:`take_over`, called once as pytest
starts, keeps two *launcher threads*, the node's at the inherited policy and
the controller's below it, and returns the test process's own thread to
SCHED_OTHER (lowering is always allowed); a process started from a launcher
thread inherits its real-time policy, any other starts at the normal one.
Started without a real-time policy (a developer's ``pytest tests/hil``, or
where ``chrt`` is not permitted), everything runs at the normal policy, as
before, and :func:`describe` says so.

The node runs above the controller: the launcher for the node (``realtime="node"``)
keeps the priority pytest was started with (``tests/hil/rt``: 20), the one for
the controller service (``realtime="controller"``) runs
:data:`NODE_ABOVE_CONTROLLER` lower (10). The simulated node stands in for
separate hardware, whose watchdog and drives no controller's work can delay; on
a shared machine a service starting up (imports, compiled-kernel loading: seconds
of CPU at its real-time priority) would otherwise hold back a node's tick, and a
second CI run's services would delay this run's watchdog reaction (seen: 456 ms
against its 360 ms bound with two runs' hil tiers at one priority). Lowering a
priority needs no privilege, so this works inside the user namespace too.

Nothing started this way may spin: the kernel leaves ordinary tasks only
``1 - sched_rt_runtime_us/sched_rt_period_us`` (5 %) of a CPU that a real-time
task keeps busy. The service's control loop and the node's tick loop sleep
until their next tick, so they take the CPU only for the work of each tick.
"""

from __future__ import annotations

import os
import subprocess
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Literal

REALTIME_POLICIES = {os.SCHED_FIFO: "SCHED_FIFO", os.SCHED_RR: "SCHED_RR"}
NODE_ABOVE_CONTROLLER = 10
"""How many real-time priority levels the simulated node runs above the controller service (module docstring)."""
Role = Literal["node", "controller"]
"""Who a real-time process or thread stands in for: the node (and devices on the bus) or the controller."""


@dataclass(frozen=True)
class Policy:
    """A real-time scheduling policy and its priority (1–99)."""

    policy: int
    priority: int

    def __str__(self) -> str:
        return f"{REALTIME_POLICIES[self.policy]} priority {self.priority}"


def current_policy() -> Policy | None:
    """The calling thread's real-time policy, or None when it runs at a normal one."""
    policy = os.sched_getscheduler(0)
    if policy not in REALTIME_POLICIES:
        return None
    return Policy(policy, os.sched_getparam(0).sched_priority)


def _lower_to(policy: Policy) -> Policy | None:
    """Set the calling thread to ``policy`` if that lowers its priority (always permitted); return its policy."""
    now = current_policy()
    if now is not None and now.policy == policy.policy and policy.priority < now.priority:
        os.sched_setscheduler(0, policy.policy, os.sched_param(policy.priority))
    return current_policy()


def _start(argv: list[str], kwargs: dict[str, Any]) -> subprocess.Popen[bytes]:
    proc: subprocess.Popen[bytes] = subprocess.Popen(argv, **kwargs)
    return proc


class Launcher:
    """One thread that keeps the real-time policy it was created with, and starts processes from there.

    A child inherits the scheduling policy of the thread that forks it, so
    ``Popen`` called on this thread starts the child at the policy. The thread
    waits on its work queue between calls (it never spins).
    """

    def __init__(self, policy: Policy, name: str = "realtime-launcher") -> None:
        self.policy = policy
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix=name)
        created = self._executor.submit(_lower_to, policy).result()  # creates the thread now, then lowers it
        if created != policy:
            raise RuntimeError(f"the launcher thread runs at {created}, not {policy}")

    def popen(self, argv: list[str], **kwargs: Any) -> subprocess.Popen[bytes]:
        """``subprocess.Popen(argv, **kwargs)``, started from the launcher thread (so at its policy)."""
        return self._executor.submit(_start, argv, kwargs).result()

    def start_thread(self, thread: threading.Thread) -> None:
        """``thread.start()`` from the launcher thread: a new thread inherits its creator's policy."""
        self._executor.submit(thread.start).result()


_launchers: dict[Role, Launcher] = {}


def take_over() -> Policy | None:
    """Keep launcher threads at this thread's real-time policy (node) and below it (controller); go back to SCHED_OTHER.

    Called once, before pytest starts any thread of its own (``tests/conftest.py``,
    ``pytest_configure``); returns the node's policy kept (None when there was none). The
    nice value stays what it was (``.ci/test`` starts the hil tiers at ``nice -n -10``).
    """
    if "node" in _launchers:
        return _launchers["node"].policy
    policy = current_policy()
    if policy is None:
        return None
    below = Policy(policy.policy, max(policy.priority - NODE_ABOVE_CONTROLLER, 1))
    _launchers["node"] = Launcher(policy, "realtime-node-launcher")
    _launchers["controller"] = Launcher(below, "realtime-controller-launcher")
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    return policy


def popen(argv: list[str], *, realtime: Role | None, **kwargs: Any) -> subprocess.Popen[bytes]:
    """Start ``argv``; with ``realtime``, at that role's real-time policy, where the test process had one."""
    if realtime is not None and realtime in _launchers:
        return _launchers[realtime].popen(argv, **kwargs)
    return _start(argv, kwargs)


def launcher_policy(role: Role) -> Policy | None:
    """The real-time policy kept for ``role`` (None: it runs at the normal policy)."""
    launcher = _launchers.get(role)
    return launcher.policy if launcher is not None else None


def start_thread(thread: threading.Thread, *, realtime: Role | None) -> None:
    """Start ``thread``; with ``realtime``, at that role's real-time policy, where the test process had one.

    For a test's instrument that stands in for a device on the bus, whose timing the
    bound under test assumes (the second sender answering each genuine frame at once): ``"node"``.
    """
    if realtime is not None and realtime in _launchers:
        _launchers[realtime].start_thread(thread)
    else:
        thread.start()


def describe() -> str:
    """Which policy the service and node of the hil tests run at, for pytest's header."""
    if not _launchers:
        return (
            "hil: the service and node run at the normal scheduling policy (pytest was not started under a "
            "real-time policy; .ci/test starts the hil tiers under `chrt --rr 20` where permitted: tests/hil/rt)"
        )
    return (
        f"hil: the node runs at {_launchers['node'].policy}, the service at {_launchers['controller'].policy} "
        "(real-time); pytest and its helpers at SCHED_OTHER"
    )


__all__ = [
    "NODE_ABOVE_CONTROLLER",
    "REALTIME_POLICIES",
    "Launcher",
    "Policy",
    "Role",
    "current_policy",
    "describe",
    "launcher_policy",
    "popen",
    "start_thread",
    "take_over",
]

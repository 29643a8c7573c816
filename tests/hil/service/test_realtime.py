"""The service the hil tests start runs at the controller's real-time policy; pytest itself at the normal one.

Under ``.ci/test`` that is SCHED_RR 10, below the node's 20 (tests/support/realtime.py): every thread of
the service, its control loop included, runs real-time, so a CPU hog on the
machine cannot delay its heartbeats past the node's watchdog.
"""

from __future__ import annotations

import os
from pathlib import Path

from tests.support.realtime import current_policy, launcher_policy
from tests.support.service import private_dir, start_service, write_config


def _thread_policies(pid: int) -> dict[str, tuple[int, int]]:
    """Each thread's (policy, real-time priority) from /proc: fields 41 and 40 of its stat (proc(5))."""
    policies = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        comm = (task / "comm").read_text().strip()
        fields = (task / "stat").read_text().rsplit(")", 1)[1].split()  # field N of proc(5) at index N - 3
        policies[f"{comm}[{task.name}]"] = (int(fields[41 - 3]), int(fields[40 - 3]))
    return policies


def test_every_thread_of_the_service_runs_at_the_controllers_policy() -> None:
    kept = launcher_policy("controller")
    expected = (kept.policy, kept.priority) if kept is not None else (os.SCHED_OTHER, 0)
    with private_dir() as directory:
        write_config(directory)
        service = start_service(directory)
        try:
            threads = _thread_policies(service.proc.pid)
        finally:
            service.stop()
    assert len(threads) > 1, threads  # the control loop's thread among them (Python 3.11 names none of them)
    assert {name: got for name, got in threads.items() if got != expected} == {}, f"expected {expected}"
    assert current_policy() is None, "pytest's own thread must run at the normal policy"

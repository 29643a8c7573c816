"""A STOP right behind the controller's first setpoint, with the node as a process of its own (issue 15).

The hil-service tier's flake — pause → resume → abort back to back tripped
the controller with "node went ARMED → RUNNING, which the controller (state
STOPPING) did not command" — over every transport. With the node in its own
process the race has a second form: an ARMED status the node sent before it
took the setpoint reaches the controller after the STOP and looks like the
stop's end; the RUNNING behind it must not trip either
(docs/safety.md#a-stop-overtaking-a-setpoint).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from millctl.api import RunState
from millctl.protocol import EStop
from tests.hil.scenario_support import Mill, is_kind, mill_on, wait_for

if TYPE_CHECKING:
    from tests.hil.conftest import Spawner, Transport

pytestmark = pytest.mark.hil

DEMO = Path(__file__).resolve().parents[2] / "config" / "recipes" / "demo.toml"
ABORT_DELAYS_S = (0.0, 0.0, 0.01, 0.02, 0.0, 0.03, 0.005, 0.05, 0.0, 0.015)
"""When the abort follows the resume, one run each: the race window is the ~50 ms between the controller's
first nonzero setpoint to an ARMED node and the node's RUNNING coming back."""


@pytest.fixture
def mill(transport: Transport, spawn: Spawner, tmp_path: Path) -> Iterator[Mill]:
    with mill_on(transport, spawn, tmp_path) as started:
        yield started


def test_pause_resume_and_abort_back_to_back_stop_cleanly_on_every_transport(mill: Mill) -> None:
    client = mill.client
    client.take_control()
    t_begin = mill.probe.now() if mill.probe is not None else 0.0
    for run, delay_s in enumerate(ABORT_DELAYS_S, 1):
        client.recipe_run(DEMO)
        wait_for(lambda: (p := client.recipe().progress) is not None and p.state == "RUNNING",
                 mill.timeout(30.0), f"run {run} to start")
        client.recipe_pause(now=True)
        client.recipe_resume()
        time.sleep(delay_s)
        client.recipe_abort()
        wait_for(lambda: not client.recipe().active, mill.timeout(30.0), f"run {run} to stop")
        status = mill.status()
        assert status["state"] == "ARMED", (
            f"run {run} (abort {delay_s * 1e3:.0f} ms after the resume): {status['state']}, {status['trip_cause']!r}"
        )
        progress = client.recipe().progress
        assert progress is not None and progress.state is RunState.ABORTED
    if mill.probe is not None:
        assert mill.probe.frames(t_begin, is_kind(EStop)) == []  # not one E-stop on the bus

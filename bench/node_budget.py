"""Item 2b, the node's tick budget: CPU fraction per 100 Hz tick, and the real-time factor of the stepped rig.

The node (``firmware_sim.node.Node``) and the controller run on python-can's
virtual bus and one :class:`~millctl.clock.ManualClock`, stepped at the node's
tick as in ``tests/unit/scenarios/rig.py``: connect, arm, ramp to a speed pair
and hold. Per tick the node's own wall time is read (``tick_mean_s``,
``tick_max_s``) and its share of the 10 ms budget reported, once with the
physics summary on the worker thread and once inline. The real-time factor is
mill time over wall time for the whole stepped loop (node + controller); the
process CPU time (``time.process_time``, which includes the worker thread) per
second of mill time is the node's true CPU load.
"""

from __future__ import annotations

import time
import uuid
from typing import Any

import can
import numpy as np

from bench.common import bench_config
from firmware_sim.node import Node
from millctl.clock import ManualClock
from millctl.controller import Controller, ControllerState

TARGET_RPM = (150.0, 800.0)
"""The speed pair of the run (inside Set A's envelope)."""


def _stepped_run(worker: str, hold_s: float) -> dict[str, Any]:
    """Connect, arm, ramp to TARGET_RPM and hold ``hold_s``; time every node tick and the whole loop."""
    config = bench_config()
    dt = config.timing.node_tick_s
    channel = f"bench-{uuid.uuid4().hex}"
    buses = [can.Bus(interface="virtual", channel=channel) for _ in range(2)]
    clock = ManualClock()
    node = Node(config, buses[0], clock, fault_injection=False, seed=0, physics_worker=worker)  # type: ignore[arg-type]
    controller = Controller(config, buses[1], clock)
    ticks: list[float] = []
    tick_cpu: list[float] = []  # the node thread's CPU time in tick(): what the tick costs, without preemption

    def step(count: int) -> None:
        for _ in range(count):
            start, cpu_start = time.perf_counter(), time.thread_time()
            node.tick()
            ticks.append(time.perf_counter() - start)
            tick_cpu.append(time.thread_time() - cpu_start)
            controller.tick()
            clock.advance(dt)

    def until(cond: Any, limit_s: float) -> None:
        for _ in range(round(limit_s / dt)):
            if cond():
                return
            step(1)

    try:
        wall0, cpu0, mill0 = time.perf_counter(), time.process_time(), clock.now()
        until(lambda: controller.state is ControllerState.DISABLED, 1.0)
        controller.arm()
        until(lambda: controller.state is ControllerState.ARMED, 1.0)
        move = controller.set_speeds(*TARGET_RPM)
        step(round((move.duration_s + hold_s) / dt))
        wall, cpu, mill = time.perf_counter() - wall0, time.process_time() - cpu0, clock.now() - mill0
        reached = node.measured_speeds_rpm
        arr = np.asarray(ticks)
        return {
            "physics_worker": worker,
            "ticks": node.tick_count,
            "mill_time_s": mill,
            "wall_s": wall,
            "process_cpu_s": cpu,
            "realtime_factor": mill / wall,
            "cpu_per_mill_second": cpu / mill,
            "tick_mean_s": node.tick_mean_s,
            "tick_median_s": float(np.median(arr)),
            "tick_p99_s": float(np.percentile(arr, 99)),
            "tick_p999_s": float(np.percentile(arr, 99.9)),
            "node_wall_s": float(arr.sum()),
            "node_realtime_factor": mill / float(arr.sum()),
            "cpu_fraction_p999": float(np.percentile(arr, 99.9)) / dt,
            "node_cpu_s": float(np.sum(tick_cpu)),
            "node_realtime_factor_cpu": mill / float(np.sum(tick_cpu)),
            "tick_cpu_p999_s": float(np.percentile(tick_cpu, 99.9)),
            "tick_cpu_fraction_p999": float(np.percentile(tick_cpu, 99.9)) / dt,
            "tick_max_s": node.tick_max_s,
            "tick_budget_s": dt,
            "cpu_fraction_mean": node.tick_mean_s / dt,
            "cpu_fraction_p99": float(np.percentile(arr, 99)) / dt,
            "cpu_fraction_max": node.tick_max_s / dt,
            "physics_computations": node.physics.computations,
            "final_measured_rpm": list(reached),
            "controller_state": str(controller.state),
        }
    finally:
        node.close()
        for bus in buses:
            bus.shutdown()


def run(quick: bool) -> dict[str, Any]:
    """Both worker modes: ``inline`` (the node's default, fixed work) and ``thread``.

    ``inline`` computes every summary the speeds ask for in the tick (the compiled kernels);
    ``thread`` skips those asked for while its worker is busy.

    ``node_realtime_factor``: mill time over the node's own time in ``tick()`` (the stepped node alone);
    ``realtime_factor``: over the whole stepped loop (node + controller on the virtual bus).
    """
    hold_s = 2.0 if quick else 20.0
    thread = _stepped_run("thread", hold_s)
    inline = _stepped_run("inline", hold_s)
    return {
        "target_rpm": list(TARGET_RPM),
        "hold_s": hold_s,
        "thread": thread,
        "inline": inline,
        "inline_over_thread_tick_mean": inline["tick_mean_s"] / thread["tick_mean_s"],
        "inline_over_thread_tick_max": inline["tick_max_s"] / thread["tick_max_s"],
    }

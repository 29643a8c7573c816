"""Level (c) of the design studies (issue 40): the compiled many-event kernel's speed and its agreement.

* **offline**: :func:`~millctl.physics.simulate.simulate_compiled` on random scenes of the :data:`OFFLINE`
  range, four revolutions each: events (impacts and detachments) per CPU second of this thread, against the
  reference engine's on the first scenes (the same run). **offline_slip**: the same with the held rods'
  slip ride (μ of Set A, :mod:`millctl.physics.wall_slide`): its slide steps are work, not events.
* **agreement_c**, **agreement_c_slip**: the compiled kernel against the reference engine event for event on
  random scenes (:func:`millctl.physics.many_agreement.many_event_agreement`, both variants), carried and
  with slip; every scene that differs is listed, drift (the same events, times apart) marked apart from a
  decision (an event one engine saw and the other did not).
* **slide_precision**: the slip ride's Runge–Kutta step against its error (one rod's first departure after a
  slide, against solve_ivp's ride) and against its cost (events per CPU second with slip), 8–64 steps a
  time scale: speed against error for the one knob of the slip ride (``slide_steps``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from bench.common import bench_config
from millctl.config import ModelVariant
from millctl.physics.many_agreement import many_event_agreement
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import SimulationResult, simulate, simulate_compiled
from millctl.physics.slip_ride import ride
from millctl.physics.wall_slide import STEPS_PER_SCALE

OFFLINE = {"rotary_rpm": (120.0, 200.0), "vibration_rpm": (400.0, 800.0)}
"""Level (c) is timed away from the micro-hops of a few rpm (thousands of events per revolution)."""
SIM_METRICS = ["impact_energy_p10_j", "impact_energy_p90_j", "sim_impact_rate_hz"]
SLIDE_POINTS_RPM = ((200.0, 800.0), (250.0, 600.0), (280.0, 500.0), (310.0, 400.0), (300.0, 700.0))
"""Where a rod carried from the bottom slips, slides and leaves (corrected variant, one rod)."""
SLIDE_STEPS = (8, 16, 32, 64)


def _offline_scenes(count: int, seed: int = 7) -> list[Scene]:
    model = MillModel.from_config(bench_config())
    rng = np.random.default_rng(seed)
    (lo_r, hi_r), (lo_v, hi_v) = OFFLINE["rotary_rpm"], OFFLINE["vibration_rpm"]
    rpm = 2.0 * np.pi / 60.0
    return [
        Scene(model, rng.uniform(lo_r, hi_r) * rpm, rng.uniform(lo_v, hi_v) * rpm, *rng.uniform(0.0, 2.0 * np.pi, 2))
        for _ in range(count)
    ]


def _events_per_cpu_s(
    scenes: list[Scene], run: Callable[[Scene, float], Any], revolutions: float
) -> tuple[int, float, float]:
    """(events, CPU s, simulated s) of ``run`` over the scenes."""
    events, cpu, simulated = 0, 0.0, 0.0
    for scene in scenes:
        t_end = revolutions * 2.0 * np.pi / scene.omega_r_rad_s
        start = time.thread_time()
        result = run(scene, t_end)
        cpu += time.thread_time() - start
        events += int(result.impacts.size + result.detachments.size)
        simulated += t_end
    return events, cpu, simulated


def offline(scenes: int, reference_scenes: int, friction: float = math.inf) -> dict[str, Any]:
    """The compiled kernel's events per CPU second of this thread, and the reference's on the first scenes."""
    chosen = _offline_scenes(scenes)
    simulate_compiled(chosen[0], 1e-3, friction=friction)  # load the compiled code
    events, cpu, simulated = _events_per_cpu_s(
        chosen, lambda s, t: simulate_compiled(s, t, friction=friction)[0], 4.0
    )
    ref_events, ref_cpu, _ = _events_per_cpu_s(
        chosen[:reference_scenes], lambda s, t: simulate(s, t, friction=friction), 4.0
    )
    return {
        "scenes": scenes, "events": events, "cpu_s": cpu, "events_per_cpu_s": events / cpu,
        "real_time_factor": simulated / cpu,
        "reference_scenes": reference_scenes, "reference_events_per_cpu_s": ref_events / ref_cpu,
        "speedup": (events / cpu) / (ref_events / ref_cpu), "friction": friction,
    }  # fmt: skip


def agreement_c(scenes: int, revolutions: float, friction: float = math.inf) -> dict[str, Any]:
    """The compiled level (c) against the reference, event for event, on random scenes of both variants."""
    model = MillModel.from_config(bench_config())
    found = many_event_agreement(model, scenes, seed=2026, revolutions=revolutions, friction=friction)
    differences = [
        f"{d.variant} {d.omega_r_rpm:.1f}/{d.omega_v_rpm:.1f} rpm, impact {d.event}"
        f"{' (drift: the same events to the end, times apart)' if d.drift else ''}: reference {d.reference}; "
        f"compiled {d.compiled}"
        for d in found.differences
    ]
    return {
        "scenes": found.scenes, "agreeing": found.agreeing, "fraction": found.fraction, "events": found.events,
        "revolutions": revolutions, "differences": differences, "decisions": len(found.decisions),
        "friction": friction,
    }  # fmt: skip


def _sliding_departures(phases: int, friction: float) -> list[tuple[Scene, float, float]]:
    """(scene, t_d, θ_d) of every one-rod scene of :data:`SLIDE_POINTS_RPM` whose solve_ivp ride leaves in a turn."""
    base = MillModel.from_config(bench_config())
    one = dataclasses.replace(base, variant=ModelVariant.CORRECTED, n_rods=1)
    rpm = 2.0 * math.pi / 60.0
    found = []
    for w_r, w_v in SLIDE_POINTS_RPM:
        for k in range(phases):
            scene = Scene(one, w_r * rpm, w_v * rpm, -0.5 * math.pi, 2.0 * math.pi * (k + 0.5) / phases)
            reference = ride(scene, "locked", horizon_s=2.0 * math.pi / scene.omega_r_rad_s, friction=friction)
            if reference.detached and reference.slip_time_s > 0.0:
                found.append((scene, reference.time_s, reference.theta_rad))
    return found


def _slip_run(friction: float, steps: int, scene: Scene, t_end: float) -> SimulationResult:
    return simulate_compiled(scene, t_end, friction=friction, slide_steps=steps)[0]


def slide_precision(quick: bool, friction: float) -> dict[str, Any]:
    """Each step count of :data:`SLIDE_STEPS`: the first departure's error against the ride, and the cost."""
    cases = _sliding_departures(6 if quick else 12, friction)
    timed = _offline_scenes(10 if quick else 40)
    rows = []
    for steps in SLIDE_STEPS:
        dt, dth, missed = 0.0, 0.0, 0
        for scene, t_d, theta_d in cases:
            run, _ = simulate_compiled(scene, 2.0 * math.pi / scene.omega_r_rad_s, friction=friction, slide_steps=steps)
            if run.detachments.size == 0:
                missed += 1
                continue
            first = run.detachments[0]
            dt = max(dt, abs(float(first["time_s"]) - t_d))
            dth = max(dth, abs(math.remainder(float(first["theta_rad"]) - theta_d, 2.0 * math.pi)))
        events, cpu, simulated = _events_per_cpu_s(timed, functools.partial(_slip_run, friction, steps), 4.0)
        rows.append({"steps": steps, "max_dt_s": dt, "max_dtheta_rad": dth, "missed": missed,
                     "events_per_cpu_s": events / cpu, "real_time_factor": simulated / cpu})  # fmt: skip
    return {"cases": len(cases), "scenes": len(timed), "friction": friction, "default": STEPS_PER_SCALE,
            "rows": rows}  # fmt: skip


def run(quick: bool, progress: Callable[[str], None] = lambda _: None) -> dict[str, Any]:
    """Every figure of this piece: carried, and with the slip ride at Set A's μ."""
    mu = MillModel.from_config(bench_config()).powder_friction
    progress("study: level (c), the compiled many-event kernel, one core")
    out: dict[str, Any] = {"offline": offline(20 if quick else 200, 3 if quick else 10)}
    progress(f"study: level (c) with the slip ride (μ = {mu}), one core")
    out["offline_slip"] = offline(20 if quick else 200, 3 if quick else 10, mu)
    progress("study: level (c), compiled against the reference event for event")
    out["agreement_c"] = agreement_c(60 if quick else 1000, 0.5)
    progress("study: level (c) with the slip ride, compiled against the reference event for event")
    out["agreement_c_slip"] = agreement_c(60 if quick else 1000, 0.5, mu)
    progress("study: level (c), the slip ride's step against its error and its cost")
    out["slide_precision"] = slide_precision(quick, mu)
    return out


def _agreement_lines(a: dict[str, Any], label: str) -> list[str]:
    decisions = f", {a['decisions']} a decision" if "decisions" in a else ""
    return [
        "",
        f"Event for event against the reference{label}: {a['agreeing']} of {a['scenes']} random scenes "
        f"({a['fraction']:.2%}; {a['events']:,} events, {a['revolutions']} revolution each, both variants"
        f"{decisions}).",
        *[f"- differs: {d}" for d in a["differences"]],
    ]


def offline_lines(st: dict[str, Any]) -> list[str]:
    """Level (c): the compiled kernel's speed and its agreement with the reference, carried and with slip."""
    o = st["offline"]
    lines = [
        f"Level (c), the compiled many-event kernel: {o['events_per_cpu_s']:.3g} events per CPU second "
        f"({o['events']:,} events of {o['scenes']} random scenes of ω_r 120–200 × ω_v 400–800 rpm, 4 revolutions "
        f"each), {o['speedup']:.0f}× the reference engine's {o['reference_events_per_cpu_s']:.3g} in the same run "
        f"({o['reference_scenes']} of the scenes).",
    ]
    if "offline_slip" in st:
        s = st["offline_slip"]
        lines += [
            "",
            f"With the held rods' slip ride (μ = {s['friction']}): {s['events_per_cpu_s']:.3g} events per CPU second "
            f"({s['events']:,} events of the same scenes; the slide steps are work, not events: the rods slide back "
            f"and slosh at the bottom, and a run costs its simulated time, {s.get('real_time_factor', math.nan):.3g}× "
            f"real time against {o.get('real_time_factor', math.nan):.3g}× carried), "
            f"{s['speedup']:.0f}× the reference engine's {s['reference_events_per_cpu_s']:.3g}.",
        ]
    if "agreement_c" in st:
        lines += _agreement_lines(st["agreement_c"], "")
    if "agreement_c_slip" in st:
        lines += _agreement_lines(st["agreement_c_slip"], f" with slip (μ = {st['agreement_c_slip']['friction']})")
    if "slide_precision" in st:
        lines += slide_precision_lines(st["slide_precision"])
    return lines


def slide_precision_lines(sp: dict[str, Any]) -> list[str]:
    """The slip ride's step: error of the first departure against solve_ivp, and events per CPU second."""
    points = ", ".join(f"{r:.0f}/{v:.0f}" for r, v in SLIDE_POINTS_RPM)
    lines = [
        "",
        f"The slip ride's step against its error and its cost (μ = {sp['friction']}): the first departure of "
        f"{sp['cases']} one-rod scenes that slide and leave ({points} rpm, corrected, cam phases apart) "
        f"against solve_ivp's ride (`slip_ride.ride`, DOP853, rtol 1e-11); the "
        f"cost on {sp['scenes']} of the random scenes above. `slide_steps` (default {sp['default']}) is the knob.",
        "",
        "| slide steps per time scale | largest departure time error (s) | largest departure angle error (rad) "
        "| events per CPU second | × real time |",
        "|---|---|---|---|---|",
    ]
    for row in sp["rows"]:
        missed = f" ({row['missed']} not left)" if row["missed"] else ""
        lines.append(
            f"| {row['steps']}{' (default)' if row['steps'] == sp['default'] else ''} | {row['max_dt_s']:.2g}{missed} "
            f"| {row['max_dtheta_rad']:.2g} | {row['events_per_cpu_s']:.3g} | {row['real_time_factor']:.3g} |"
        )
    return lines


__all__ = ["OFFLINE", "SIM_METRICS", "agreement_c", "offline", "offline_lines", "run", "slide_precision"]

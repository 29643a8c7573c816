"""Does the compiled level (c) see the reference's events? Random scenes, compared event for event.

The reference is :func:`millctl.physics.simulate.simulate` (numpy/scipy, the oracle), the candidate
:func:`~millctl.physics.simulate.simulate_compiled` (:mod:`millctl.physics.kernels.many_event`). A scene
agrees when both record the same number of detachments and of impacts, and impact k of both has the same
rod and partner and times within ``time_rtol`` of the run's length (1e-6 by default: over a thousand events
of a chaotic pile the engines' 1e-16 rounding differences grow to ~1e-9 s) — every event, micro-hops
included; simultaneous impacts (times within the tolerance) may come in any order. A scene whose records
are the same events with times drifted further apart (the same bodies in the same order within
:data:`DRIFT_RTOL`: a chaotic pile amplifies rounding) is reported as drift, apart from a decision difference.
Scenes: :func:`millctl.physics.agreement.random_scenes` (uniform ω_r, ω_v, θ0, α0, r_d),
half in each model variant, simulated for ``revolutions`` of the vial. Used by the unit test (a few dozen
seeded scenes) and by ``python -m bench`` (the ``agreement_c`` row, a thousand).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from millctl.config.models import ModelVariant
from millctl.physics.agreement import random_scenes
from millctl.physics.model import MillModel
from millctl.physics.simulate import SimulationResult, simulate, simulate_compiled

DRIFT_RTOL = 1e-3
"""A difference is drift when the records agree with times this loose (× the run's length)."""


@dataclass(frozen=True)
class SceneDifference:
    """The first event where the engines part, for the report."""

    omega_r_rpm: float
    omega_v_rpm: float
    variant: str
    event: int
    """Index of the first impact that differs (or the shorter record's length)."""
    reference: str
    compiled: str
    drift: bool = False
    """The same events (bodies, order and counts) whose times drifted apart beyond the tolerance (chaos: each
    rod–rod impact amplifies the engines' 1e-16 rounding differences), not a decision the engines took apart."""


@dataclass
class ManyEventAgreement:
    """Counted over the scenes compared."""

    scenes: int = 0
    agreeing: int = 0
    events: int = 0
    """Impacts and detachments of the compiled runs."""
    differences: list[SceneDifference] = field(default_factory=list)

    @property
    def fraction(self) -> float:
        """Share of the scenes that agree event for event."""
        return self.agreeing / self.scenes if self.scenes else math.nan

    @property
    def decisions(self) -> list[SceneDifference]:
        """The differences that are not drift: a contact or detachment one engine saw and the other did not."""
        return [d for d in self.differences if not d.drift]


def _describe(result: SimulationResult, k: int) -> str:
    if k >= len(result.impacts):
        return f"no impact {k} ({len(result.impacts)} impacts, {len(result.detachments)} detachments)"
    row = result.impacts[k]
    return (
        f"rod {int(row['rod'])} on {int(row['partner'])} at t = {float(row['time_s']):.12g} s, "
        f"v_n = {float(row['normal_velocity_m_s']):.3g} m/s, flight {float(row['flight_time_s']):.3g} s"
    )


def first_difference(reference: SimulationResult, compiled: SimulationResult, time_rtol: float = 1e-6) -> int | None:
    """Index of the first impact where the records part (None: the same events).

    Impacts whose times agree within the tolerance are simultaneous and may come in any order (rods in
    the same flight relative to the vial land together, and rounding picks which one is found first).
    """
    a, b = reference.impacts, compiled.impacts
    tol = time_rtol * max(reference.t_end_s, 1e-300)
    k, n = 0, min(len(a), len(b))
    while k < n:
        t_k = float(a["time_s"][k])
        end_a = end_b = k
        while end_a < len(a) and abs(float(a["time_s"][end_a]) - t_k) <= tol:
            end_a += 1
        while end_b < len(b) and abs(float(b["time_s"][end_b]) - t_k) <= tol:
            end_b += 1
        bodies_a = sorted(zip(a["rod"][k:end_a].tolist(), a["partner"][k:end_a].tolist(), strict=True))
        bodies_b = sorted(zip(b["rod"][k:end_b].tolist(), b["partner"][k:end_b].tolist(), strict=True))
        if end_a == k or bodies_a != bodies_b:
            return k
        k = end_a
    if len(a) != len(b) or len(reference.detachments) != len(compiled.detachments):
        return n
    return None


def many_event_agreement(
    model: MillModel,
    count: int,
    seed: int,
    revolutions: float = 1.0,
    time_rtol: float = 1e-6,
    friction: float = math.inf,
) -> ManyEventAgreement:
    """Compare ``count`` random scenes (half paper, half corrected) over ``revolutions`` each.

    ``friction``: μ of the held rods' slip ride in both engines (inf: carried, the paper's picture).
    """
    out = ManyEventAgreement()
    variants = (ModelVariant.PAPER, ModelVariant.CORRECTED)
    scenes = [
        *random_scenes(dataclasses.replace(model, variant=variants[0]), count // 2, seed),
        *random_scenes(dataclasses.replace(model, variant=variants[1]), count - count // 2, seed + 1),
    ]
    for scene in scenes:
        turn = scene.omega_r_rad_s if scene.omega_r_rad_s > 0.0 else max(scene.omega_v_rad_s, 1.0)
        t_end = revolutions * 2.0 * math.pi / turn
        reference = simulate(scene, t_end, friction=friction)
        compiled, _ = simulate_compiled(scene, t_end, friction=friction)
        k = first_difference(reference, compiled, time_rtol)
        out.scenes += 1
        out.events += int(compiled.impacts.size + compiled.detachments.size)
        if k is None:
            out.agreeing += 1
            continue
        rpm = 60.0 / (2.0 * math.pi)
        out.differences.append(
            SceneDifference(
                scene.omega_r_rad_s * rpm,
                scene.omega_v_rad_s * rpm,
                scene.model.variant.value,
                k,
                _describe(reference, k),
                _describe(compiled, k),
                first_difference(reference, compiled, DRIFT_RTOL) is None,
            )
        )
    return out


__all__ = [
    "DRIFT_RTOL",
    "ManyEventAgreement",
    "SceneDifference",
    "first_difference",
    "many_event_agreement",
]

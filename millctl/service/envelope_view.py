"""``GET /v1/envelope``: the limit curve the interlock enforces, every other law, and the regime warning.

The curve is the controller's own :class:`~millctl.safety.Envelope` sampled on
a grid; the warning comes from :func:`millctl.safety.regime.regime_warning`,
the one function ``millctl limits`` also prints, so the TUI and the CLI say
the same number.
"""

from __future__ import annotations

import numpy as np

from millctl.api import EnvelopeOut, EnvelopePoint, RegimeOut
from millctl.physics.limits import LAWS, omega_r_max
from millctl.safety import Envelope
from millctl.safety.regime import regime_warning
from millctl.service.journal import finite
from millctl.units import rad_s_to_rpm, rpm_to_rad_s


def envelope_out(env: Envelope, points: int) -> EnvelopeOut:
    """The envelope on ``points`` vibration speeds from 0 to the drive's maximum."""
    w_v = np.linspace(0.0, env.vibration_max_rpm, points)
    limit, law_limit, every = env.omega_r_limit_rpm(w_v), env.law_limit_rpm(w_v), env.every_cycle(w_v)
    laws = {law.value: rad_s_to_rpm(omega_r_max(law, env.params, rpm_to_rad_s(w_v))) for law in LAWS}
    warning = regime_warning(env)
    regime = None if warning is None else RegimeOut(
        above_vibration_rpm=warning.above_vibration_rpm, summary=warning.summary, message=warning.message)
    return EnvelopeOut(
        law=env.law.value, description=env.description, margin=env.margin, rotary_max_rpm=env.rotary_max_rpm,
        vibration_max_rpm=env.vibration_max_rpm, furnace_min_c=env.furnace_min_c, furnace_max_c=env.furnace_max_c,
        max_heating_rate_c_per_min=env.max_heating_rate_c_per_min, regime=regime,
        points=[
            EnvelopePoint(vibration_rpm=float(w_v[i]), limit_rotary_rpm=finite(float(limit[i])),
                          law_limit_rotary_rpm=finite(float(law_limit[i])), law_is_every_cycle=bool(every[i]),
                          laws_rotary_rpm={name: finite(float(values[i])) for name, values in laws.items()})
            for i in range(points)
        ],
    )


__all__ = ["envelope_out"]

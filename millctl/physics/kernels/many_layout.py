"""Array layouts of the compiled many-event kernel (:mod:`.many_event`): rod bookkeeping, impact and detachment rows.

A rod's motion is a row of the shared state columns (``_S_*`` in :mod:`.layout`: flying flag, t0,
pinned angle, flight start and velocity, n_d, cam phasor). What the event loop of level (c) keeps
beside it, one row a rod, is :data:`ROD_BOOK`; what it writes, one row an event, is :data:`IMPACT`
and :data:`DETACHMENT` (the columns of :data:`millctl.physics.simulate.IMPACT_DTYPE` and
``DETACHMENT_DTYPE`` that the kernel fills; the cam phase α is added from the time by the caller), and
what it sums over the run :data:`TOTALS`.
"""

from __future__ import annotations

ROD_BOOK = ("next_event_s", "unsupported", "from_wall", "bounces", "ends", "direction", "theta_rad", "rate_rad_s",
            "slid_s", "changes")  # fmt: skip
"""Columns of a rod's bookkeeping row: its next held event (s; inf: none before the end), 1.0 when that is a
detachment at the start of its search with N < 0 (not a falling zero), 1.0 while its flight began on
the wall (the wall gap has the departure's triple root), and its rod–rod impacts in the current flight;
its slip ride (:mod:`millctl.physics.wall_slide`): what the next held event is (DETACH, SLIDE_STEP or
REGRIP), the slide's direction s (0 carried), φ and φ̇ at that event, the time slid since it was put on
the wall, and its stick ↔ slide changes since."""

(_B_DET, _B_UNSUP, _B_FROM_WALL, _B_BOUNCES, _B_ENDS, _B_DIR, _B_PHI, _B_RATE, _B_SLID, _B_CHANGES) = range(
    len(ROD_BOOK)
)

TOTALS = ("slide_s", "overlap_s")
"""What a run sums, beside its rows (:class:`millctl.physics.simulate.SimulationResult`'s fields of the same
names): the rod-seconds slid, and of those the slide steps begun inside another held rod."""

_T_SLIDE, _T_OVERLAP = range(len(TOTALS))

IMPACT = (
    "time_s",
    "rod",
    "partner",
    "x_m",
    "y_m",
    "theta_rad",
    "normal_velocity_m_s",
    "tangential_velocity_m_s",
    "speed_abs_m_s",
    "energy_j",
    "flight_time_s",
    "counted",
)
"""Columns of an impact row (lab frame, SI); ``counted`` 1.0 when the energy reaches the impact threshold
(below it the landing is a micro-hop, :func:`millctl.studies.loads.impact_threshold_j`)."""

(_I_T, _I_ROD, _I_PARTNER, _I_X, _I_Y, _I_TH, _I_VN, _I_VT, _I_SPEED, _I_ENERGY, _I_FLIGHT, _I_COUNTED) = range(
    len(IMPACT)
)

DETACHMENT = ("time_s", "rod", "theta_rad", "slid_s")
"""Columns of a detachment row (``slid_s``: the time the rod slid on the wall before it left, 0 carried)."""

(_D_T, _D_ROD, _D_TH, _D_SLID) = range(len(DETACHMENT))

SETTLE_SPEED_FACTOR = 0.01
"""A rod–rod impact slower than this × √(g r_r) settles the rod into the pile (as :mod:`..simulate`)."""
MIN_HOP_RTOL = 1e-6
"""A wall landing after a flight shorter than this × the scan's step ends a Zeno chain (as :mod:`..simulate`)."""
MAX_BOUNCES = 20
"""More rod–rod impacts than this in one flight settle the rod too."""
SCAN_SAMPLES = 32
"""Samples a chunk of the bracketing scan (as :mod:`millctl.physics.events`)."""

__all__ = [
    "DETACHMENT", "IMPACT", "MAX_BOUNCES", "MIN_HOP_RTOL", "ROD_BOOK", "SCAN_SAMPLES", "SETTLE_SPEED_FACTOR", "TOTALS"
]  # fmt: skip

"""The single source of truth for every limit: the envelope, every check on it, and safe ramps.

Imported by the controller, recipes, the TUI and the node: the controller
refuses, the planner plans, the TUI greys out and the node rejects, all here.
"""

from millctl.safety.envelope import DOC_REF, Envelope, InterlockRefused, Refusal, Verdict
from millctl.safety.ramps import STANDSTILL, RampPlanner, Segment, SpeedPoint, Trajectory, first_violation

__all__ = [
    "DOC_REF",
    "STANDSTILL",
    "Envelope",
    "InterlockRefused",
    "RampPlanner",
    "Refusal",
    "Segment",
    "SpeedPoint",
    "Trajectory",
    "Verdict",
    "first_violation",
]

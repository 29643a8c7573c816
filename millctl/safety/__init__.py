"""The single source of truth for every limit: the envelope and every check on it.

Imported by the controller, the ramp planner, recipes, the TUI and the node.
"""

from millctl.safety.envelope import DOC_REF, Envelope, InterlockRefused, Refusal, Verdict

__all__ = ["DOC_REF", "Envelope", "InterlockRefused", "Refusal", "Verdict"]

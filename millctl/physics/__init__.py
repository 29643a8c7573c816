"""The paper's physics as pure numpy/scipy functions (no I/O, no CAN).

Levels of detail (docs/model.md):

* (a) interlock — :mod:`.limits`, closed forms only (microseconds);
* (b) node telemetry — :func:`.telemetry.revolution_summary` (about a millisecond);
* (c) offline — :mod:`.simulate`, the multi-rod event simulation.

Building blocks: :mod:`.model` (parameters, scene), :mod:`.kinematics` (eqs 1–7),
:mod:`.detachment`, :mod:`.flight` (eq. 10), :mod:`.events` (eqs 11–14, exact),
:mod:`.impact` (eqs 18–27); :mod:`.slip` (where the no-slip carriage fails, pure) and
:mod:`.slip_ride` (stick → slip → detach with the rod's spin); :mod:`.errata` prints the
errata table's figures.
"""

from millctl.physics.model import MillModel, Scene
from millctl.physics.telemetry import RevolutionSummary, revolution_summary

__all__ = ["MillModel", "RevolutionSummary", "Scene", "revolution_summary"]

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

The names below are re-exported lazily (PEP 562): importing the interlock's
:mod:`.limits` loads this package, and must not load numba and scipy with it (the
interlock and the controller are closed forms; tests/unit/service/test_startup_imports.py).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from millctl.physics.model import MillModel, Scene
    from millctl.physics.telemetry import RevolutionSummary, revolution_summary

__all__ = ["MillModel", "RevolutionSummary", "Scene", "revolution_summary"]

_HOME = {
    "MillModel": "millctl.physics.model",
    "Scene": "millctl.physics.model",
    "RevolutionSummary": "millctl.physics.telemetry",
    "revolution_summary": "millctl.physics.telemetry",
}


def __getattr__(name: str) -> Any:
    """Import a re-exported name's module on first use (PEP 562)."""
    try:
        home = _HOME[name]
    except KeyError:
        raise AttributeError(f"module 'millctl.physics' has no attribute {name!r}") from None
    return getattr(importlib.import_module(home), name)

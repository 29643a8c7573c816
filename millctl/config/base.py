"""The base of every configuration model: unknown keys rejected, frozen, defaults validated.

Klipper's ``check_unused_options`` in pydantic's words; shared by
:mod:`millctl.config.models` and :mod:`millctl.config.drives` without a cycle.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class StrictModel(BaseModel):
    """A configuration section: an unknown key is an error, a value is checked when read and never changed after."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


__all__ = ["StrictModel"]

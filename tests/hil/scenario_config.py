"""The hil scenarios' configuration: the config file each mill runs with, scaled for the VM.

``write_config`` writes the backend's shipped configuration with the
scenario's transport and, in the VM, every timing bound scaled by the VM's
measured slowdown (``vm_scaled``; the drives dilated to match), each held at
its model's upper bound (``upper_bound``). Split out of
:mod:`tests.hil.scenario_support`, which re-exports every name.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel

from millctl.config.loader import packaged_file
from millctl.config.models import Furnace, Interlock, Timing
from tests.hil.conftest import REPO
from tests.hil.probe import bound_scale

if TYPE_CHECKING:
    from tests.hil.conftest import Transport


# --- config ---------------------------------------------------------------------------------------------------


def _toml_value(value: Any) -> str:
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + " }"
    return json.dumps(value)


VM_SCALED_KEYS: dict[str, type[BaseModel]] = {
    "watchdog_timeout_s": Timing,
    "challenge_lifetime_s": Timing,
    "setpoint_period_s": Timing,
    "min_setpoint_expiry_s": Timing,
    "min_stale_s": Interlock,
    "startup_grace_s": Interlock,
    "command_confirm_s": Interlock,
    "command_repeat_s": Interlock,
    "setpoint_refresh_s": Furnace,
}
"""Periods and timeouts of the config multiplied by the VM's measured slowdown there (and their config section).

Python under emulation runs many times slower (``tests/vm/run`` measures how much), so it cannot
meet the host's periods: frames arrive in bursts, and a setpoint step that the node allows per
``setpoint_period_s`` is refused when two frames arrive together; the stale, refresh, start-up
grace and challenge bounds would expire between two slow ticks. Scaling them all by one factor
keeps their ratios. A scaled value is held at its field's upper bound in the config model (e.g.
``setpoint_refresh_s`` ≤ 60 s), so that the config stays valid at any factor.
"""


def upper_bound(section: type[BaseModel], key: str) -> float:
    """The largest value the config model accepts for ``key`` (its ``le``/``lt`` constraint; inf when none)."""
    bound = math.inf
    for constraint in section.model_fields[key].metadata:
        for name in ("le", "lt"):
            if (value := getattr(constraint, name, None)) is not None:
                bound = min(bound, float(value))
    return bound


def vm_scaled(key: str, value: float, factor: float) -> float:
    """``value`` of the config key ``key`` times ``factor``, held at the key's upper bound."""
    return min(value * factor, upper_bound(VM_SCALED_KEYS[key], key))


def _scale_keys(text: str, factor: float) -> str:
    """``text`` with each of ``VM_SCALED_KEYS`` multiplied by ``factor`` (held at its upper bound)."""
    for key in VM_SCALED_KEYS:

        def scaled(match: re.Match[str], key: str = key) -> str:
            return f"{match[1]}{vm_scaled(key, float(match[2]), factor):g}"

        text, found = re.subn(rf"^({key}\s*=\s*)([0-9.]+)", scaled, text, flags=re.MULTILINE)
        assert found == 1, f"{key} is not in the packaged mill.toml"
    return text


def _dilate_drives(text: str, factor: float) -> str:
    """``text`` with both drives' ``max_accel_rpm_s`` divided by ``factor``."""
    text, found = re.subn(
        r"^(max_accel_rpm_s\s*=\s*)([0-9.]+)", lambda m: f"{m[1]}{float(m[2]) / factor:g}", text, flags=re.MULTILINE
    )
    assert found == 2, "the packaged mill.toml should set max_accel_rpm_s for the rotary and the vibration drive"
    return text


BACKEND_CONFIGS = {"millbus": "mill.toml", "cia402": "mill-cia402.toml"}
"""The shipped configuration of each drive backend (``config/``): the same mill, its drives behind the millbus
node or standard CiA 402 drives (issue 36)."""


def write_config(
    directory: Path, transport: Transport, *, dilate_drives: bool = False, backend: str = "millbus"
) -> Path:
    """The packaged config (parameter Set A) with this transport's ``[bus]`` and a ``[service]`` in ``directory``.

    Inside the VM the timeouts in ``VM_SCALED_KEYS`` are multiplied by ``bound_scale()`` (the measured
    slowdown): the VM checks behaviour and frame flow, the host the tight timing. ``dilate_drives``
    also divides the drives' accelerations by it there, so that time is dilated throughout: a rate
    rule (the node's step bound: its rate × its window, the watchdog timeout) then allows in rpm what
    it allows on the host, at the cost of ramps that many times longer. For the scenarios whose
    subject is that rule; the others keep the host's drives.
    """
    base = packaged_file("mill.toml") if backend == "millbus" else REPO / "config" / BACKEND_CONFIGS[backend]
    text = base.read_text(encoding="utf-8")
    head = text.partition("[bus]")[0]
    if bound_scale() > 1.0:
        head = _scale_keys(head, bound_scale())
        if dilate_drives:
            head = _dilate_drives(head, bound_scale())
    sections = {
        "bus": transport.bus_config_fields(),
        "service": {"socket_path": str(directory / "mill.sock"), "records_dir": str(directory / "records")},
    }
    body = "".join(
        f"[{name}]\n" + "".join(f"{key} = {_toml_value(value)}\n" for key, value in fields.items()) + "\n"
        for name, fields in sections.items()
    )
    path = directory / "mill.toml"
    path.write_text(head + body, encoding="utf-8")
    return path

"""Find, read and validate the mill configuration.

Precedence: ``--config FILE`` > ``$MILLCTL_CONFIG`` > ``./config/mill.toml`` >
the default packaged with millctl. An invalid file raises :class:`ConfigError`
with one line per problem naming the file, the field, the value and the bound.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from millctl.config.models import MillConfig
from millctl.errors import ConfigError, InvalidFileError
from millctl.files import MAX_TOML_DEPTH, nesting_depth, parse_toml, read_toml

ENV_VAR = "MILLCTL_CONFIG"
LOCAL_PATH = Path("config") / "mill.toml"

M = TypeVar("M", bound=BaseModel)


_BOUND_WORDS = {
    "gt": "> {}",
    "ge": "≥ {}",
    "lt": "< {}",
    "le": "≤ {}",
    "expected": "one of {}",
    "min_length": "at least {} items",
    "max_length": "at most {} items",
}


@dataclass(frozen=True)
class LoadedConfig:
    """A validated configuration together with where it came from."""

    config: MillConfig
    source: str
    sha256: str


GENERIC_EDS = "cia402-drive.eds"
"""The generic CiA 402 velocity drive's EDS shipped in ``config/`` and ``millctl/data``."""


def packaged_file(name: str) -> Path:
    """Path of a data file shipped inside the package (``millctl/data``)."""
    return Path(str(resources.files("millctl.data").joinpath(name)))


def resolve_config_path(explicit: str | os.PathLike[str] | None = None) -> Path:
    """Pick the config file by precedence: explicit > env > ./config/mill.toml > packaged."""
    if explicit:
        return Path(explicit)
    from_env = os.environ.get(ENV_VAR, "").strip()
    if from_env:
        return Path(from_env)
    if LOCAL_PATH.is_file():
        return LOCAL_PATH
    return packaged_file("mill.toml")


def format_validation_errors(source: str, error: ValidationError) -> list[str]:
    """One line per pydantic error: file, dotted field, value, and the bound that failed."""
    lines = []
    for item in error.errors(include_url=False):
        field = ".".join(str(part) for part in item["loc"]) or "(top level)"
        ctx = item.get("ctx") or {}
        bounds = [fmt.format(ctx[key]) for key, fmt in _BOUND_WORDS.items() if key in ctx]
        value = item.get("input")
        shown = "(missing)" if item["type"] == "missing" else repr(value)
        if item["type"] == "extra_forbidden":
            lines.append(f"{source}: {field}: unknown key (value {shown}); check its spelling")
            continue
        message = item["msg"].removeprefix("Value error, ")
        bound = f" (bound: {', '.join(bounds)})" if bounds else ""
        if isinstance(value, dict) and item["type"] == "value_error":
            lines.append(f"{source}: {field}: {message}")
        else:
            lines.append(f"{source}: {field} = {shown}: {message}{bound}")
    return lines


def validate_as(
    model: type[M], data: dict[str, Any], source: str, error: type[InvalidFileError] = ConfigError
) -> M:
    """Validate a dict against a model, turning pydantic's errors into ``error`` (one line each)."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise error(source, format_validation_errors(source, exc)) from None


def load_config(path: str | os.PathLike[str] | None = None) -> LoadedConfig:
    """Load and validate the mill configuration chosen by precedence."""
    chosen = resolve_config_path(path)
    data, raw = read_toml(chosen)
    _resolve_eds_paths(data, chosen.parent)
    config = validate_as(MillConfig, data, str(chosen))
    return LoadedConfig(config=config, source=str(chosen), sha256=hashlib.sha256(raw).hexdigest())


def _resolve_eds_paths(data: dict[str, Any], base: Path) -> None:
    """Each CiA 402 drive's ``eds``: "" → the shipped generic EDS; a relative path → from the config's folder."""
    drives = data.get("drives")
    if not isinstance(drives, dict):
        return
    for motor in ("rotary", "vibration"):
        drive = drives.get(motor)
        cia402 = drive.get("cia402") if isinstance(drive, dict) else None
        if not isinstance(cia402, dict):
            continue
        eds = cia402.get("eds", "")
        if not isinstance(eds, str):
            continue  # the model names the wrong type
        cia402["eds"] = str(packaged_file(GENERIC_EDS)) if not eds else str(base / eds)


def default_config() -> MillConfig:
    """The packaged default configuration (parameter Set A)."""
    return load_config(packaged_file("mill.toml")).config


__all__ = [
    "ENV_VAR",
    "GENERIC_EDS",
    "MAX_TOML_DEPTH",
    "LoadedConfig",
    "default_config",
    "format_validation_errors",
    "load_config",
    "nesting_depth",
    "packaged_file",
    "parse_toml",
    "read_toml",
    "resolve_config_path",
    "validate_as",
]

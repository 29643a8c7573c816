"""Validated configuration: models (:mod:`.models`) and loading (:mod:`.loader`)."""

from millctl.config.loader import (
    ENV_VAR,
    LoadedConfig,
    default_config,
    format_validation_errors,
    load_config,
    packaged_file,
    read_toml,
    resolve_config_path,
    validate_as,
)
from millctl.config.models import (
    G_M_S2,
    Bus,
    CamShape,
    Drive,
    Furnace,
    Interlock,
    LimitLaw,
    Material,
    MillConfig,
    ModelVariant,
    Timing,
)

__all__ = [
    "ENV_VAR",
    "G_M_S2",
    "Bus",
    "CamShape",
    "Drive",
    "Furnace",
    "Interlock",
    "LimitLaw",
    "LoadedConfig",
    "Material",
    "MillConfig",
    "ModelVariant",
    "Timing",
    "default_config",
    "format_validation_errors",
    "load_config",
    "packaged_file",
    "read_toml",
    "resolve_config_path",
    "validate_as",
]

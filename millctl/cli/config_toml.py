"""``config show``'s text: the configuration in force as TOML, each value with where it came from.

Every value is one of: set in the file (which the ``--config`` flag,
``$MILLCTL_CONFIG``, ``./config/mill.toml`` or the packaged default chose), or
millctl's default (the key is absent from the file); the service's socket and
records folder, when the file leaves them empty, by convention from the
environment (``$RUNTIME_DIRECTORY``, ``$XDG_RUNTIME_DIR``, …: docs/deployment.md).
The text is valid TOML: read back, it is the same configuration.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from millctl.config.loader import ENV_VAR, LOCAL_PATH, LoadedConfig, read_toml


def chosen_by(explicit: str | None) -> str:
    """Which rule picked the config file: the flag, the environment, the working folder, or the package."""
    if explicit:
        return "the --config flag"
    if os.environ.get(ENV_VAR, "").strip():
        return f"${ENV_VAR} (environment)"
    if LOCAL_PATH.is_file():
        return f"./{LOCAL_PATH} in the working folder"
    return "the packaged default (no --config, no $MILLCTL_CONFIG, no ./config/mill.toml)"


def toml_value(key: str, value: Any) -> str:
    """``value`` in TOML syntax (permission bits in octal, as chmod writes them)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return f"0o{value:o}" if key.endswith("_mode") else str(value)
    if isinstance(value, float):
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return "nan" if math.isnan(value) else repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(key, v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_key(k)} = {toml_value(k, v)}" for k, v in value.items()) + "}"
    raise TypeError(f"no TOML form for {key} = {value!r}")


def _key(key: str) -> str:
    return key if key.replace("_", "").replace("-", "").isalnum() else json.dumps(key)


def _in_file(raw: dict[str, Any], path: tuple[str, ...]) -> bool:
    node: Any = raw
    for part in path:
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


def _is_table(value: Any) -> bool:
    return isinstance(value, dict) and bool(value)


def origins(loaded: LoadedConfig) -> dict[str, str]:
    """Dotted key → ``file`` or ``default``, for every value of the configuration (a non-empty dict is a table)."""
    raw, _ = read_toml(Path(loaded.source))
    found: dict[str, str] = {}

    def walk(data: dict[str, Any], path: tuple[str, ...]) -> None:
        for key, value in data.items():
            if _is_table(value):
                walk(value, (*path, key))
            else:
                found[".".join((*path, key))] = "file" if _in_file(raw, (*path, key)) else "default"

    walk(loaded.config.model_dump(mode="json"), ())
    return found


def render(loaded: LoadedConfig, explicit: str | None, conventions: dict[str, str]) -> str:
    """The configuration as TOML with a comment per value saying where it came from.

    ``conventions``: dotted key → the path the convention gives an empty value (socket, records) and its source.
    """
    where = origins(loaded)
    lines = [
        f"# config {loaded.source}, chosen by {chosen_by(explicit)}; sha256 {loaded.sha256[:16]}",
        f"# rod mass m = {loaded.config.rod_mass_kg:.5f} kg (derived, not a setting)",
        "# after each value: 'file' (set in that file) or 'default' (millctl's, the file does not set it)",
    ]

    def table(data: dict[str, Any], path: tuple[str, ...]) -> None:
        scalars = {k: v for k, v in data.items() if not _is_table(v)}
        tables = {k: v for k, v in data.items() if _is_table(v)}
        if path and scalars:
            lines.extend(["", f"[{'.'.join(_key(p) for p in path)}]"])
        for key, value in scalars.items():
            dotted = ".".join((*path, key))
            origin = where.get(dotted, "default")
            if value is None:
                lines.append(f"# {_key(key)} is not set ({origin})")
                continue
            note = f"; {conventions[dotted]}" if dotted in conventions and value == "" else ""
            lines.append(f"{_key(key)} = {toml_value(key, value)}  # {origin}{note}")
        for key, value in tables.items():
            table(value, (*path, key))

    table(loaded.config.model_dump(mode="json"), ())
    return "\n".join(lines) + "\n"


__all__ = ["chosen_by", "origins", "render", "toml_value"]

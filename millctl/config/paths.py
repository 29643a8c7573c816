"""Where the service lives: its socket and its records, by platform convention unless the config says.

=============================  ==========================================  ======================================
who runs it                    socket (``service.socket_path``)            records (``service.records_dir``)
=============================  ==========================================  ======================================
systemd unit                   ``$RUNTIME_DIRECTORY/millctl.sock``         ``$STATE_DIRECTORY/records``
                               (``RuntimeDirectory=millctl``:              (``StateDirectory=millctl``:
                               ``/run/millctl``)                           ``/var/lib/millctl``)
a user                         ``$XDG_RUNTIME_DIR/millctl/millctl.sock``   ``$XDG_STATE_HOME/millctl/records``
                                                                           (``~/.local/state/millctl/records``)
root without systemd           ``/run/millctl/millctl.sock``               ``/var/lib/millctl/records``
=============================  ==========================================  ======================================

Without ``$XDG_RUNTIME_DIR`` a user's socket goes to ``/tmp/millctl-<uid>/``
(created 0700). A path written in the config wins; a relative one is taken
from the folder of the config file that names it (never from the working
folder, which differs between a service and its clients). ``--socket`` wins
over all. Clients resolve the socket the same way, so a client in any folder
finds the service of the same configuration (docs/deployment.md).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from millctl.config.loader import LoadedConfig

APP = "millctl"
SOCKET_NAME = "millctl.sock"
SYSTEM_RUNTIME_DIR = Path("/run") / APP
SYSTEM_STATE_DIR = Path("/var/lib") / APP


def _env_dir(name: str) -> Path | None:
    """The first directory of a (possibly colon-separated, as systemd writes it) environment variable."""
    value = os.environ.get(name, "").split(":")[0].strip()
    return Path(value) if value and os.path.isabs(value) else None


def runtime_dir() -> Path:
    """The folder of the service socket by convention (see the module docstring)."""
    systemd = _env_dir("RUNTIME_DIRECTORY")
    if systemd is not None:
        return systemd
    xdg = _env_dir("XDG_RUNTIME_DIR")
    if xdg is not None:
        return xdg / APP
    if os.geteuid() == 0:
        return SYSTEM_RUNTIME_DIR
    return Path("/tmp") / f"{APP}-{os.geteuid()}"


def state_dir() -> Path:
    """The folder of the records by convention (see the module docstring)."""
    systemd = _env_dir("STATE_DIRECTORY")
    if systemd is not None:
        return systemd
    xdg = _env_dir("XDG_STATE_HOME")
    if xdg is not None:
        return xdg / APP
    if os.geteuid() == 0:
        return SYSTEM_STATE_DIR
    return Path.home() / ".local" / "state" / APP


def _from_config(value: str, loaded: LoadedConfig) -> Path:
    """A configured path; a relative one from the config file's folder."""
    path = Path(value).expanduser()
    return path if path.is_absolute() else Path(loaded.source).resolve().parent / path


@dataclass(frozen=True)
class ServicePaths:
    """The resolved socket and records folder of one configuration."""

    socket: Path
    records_dir: Path
    socket_from: str
    """Where the socket path came from: ``--socket``, ``config`` or ``convention``."""


def service_paths(loaded: LoadedConfig, socket_override: str | os.PathLike[str] | None = None) -> ServicePaths:
    """Resolve the socket and records folder of ``loaded`` (``socket_override``: ``--socket``)."""
    service = loaded.config.service
    if socket_override:
        socket, socket_from = Path(socket_override).expanduser().absolute(), "--socket"
    elif service.socket_path:
        socket, socket_from = _from_config(service.socket_path, loaded), "config"
    else:
        socket, socket_from = runtime_dir() / SOCKET_NAME, "convention"
    records = _from_config(service.records_dir, loaded) if service.records_dir else state_dir() / "records"
    return ServicePaths(socket=socket, records_dir=records, socket_from=socket_from)


__all__ = [
    "SOCKET_NAME",
    "SYSTEM_RUNTIME_DIR",
    "SYSTEM_STATE_DIR",
    "ServicePaths",
    "runtime_dir",
    "service_paths",
    "state_dir",
]

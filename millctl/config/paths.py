"""Where the service lives: its socket and its records, by platform convention unless the config says.

=============================  ==============================================  =====================================
who runs it                    socket (``service.socket_path``)                records (``service.records_dir``)
=============================  ==============================================  =====================================
systemd unit                   ``$RUNTIME_DIRECTORY/millctl.sock``             ``$STATE_DIRECTORY/records``
                               (``RuntimeDirectory=millctl``:                  (``StateDirectory=millctl``:
                               ``/run/millctl``)                               ``/var/lib/millctl``)
anyone else, root included     ``$XDG_RUNTIME_DIR/millctl/[INSTANCE/]``        ``$XDG_STATE_HOME/millctl/[INSTANCE/]``
                               ``millctl.sock``                                ``records`` (``~/.local/state/…``)
=============================  ==============================================  =====================================

The user folders are platformdirs' (``user_runtime_dir``, ``user_state_dir``):
without a usable ``$XDG_RUNTIME_DIR`` the socket goes to ``/tmp/runtime-<uid>/millctl``.
Root without systemd is a user like any other here, so nothing lands in the
system folders that every clone would share. ``INSTANCE`` is
:func:`instance_name`: a config file other than the packaged default (a clone's
``config/mill.toml``) gets folders of its own, so two clones never share a
socket or continue each other's event numbers. A path written in the config
wins; a relative one is taken from the folder of the config file that names it
(never from the working folder, which differs between a service and its
clients). ``--socket`` wins over all. Clients resolve the socket the same way,
so a client in any folder finds the service of the same configuration
(docs/deployment.md).
"""

from __future__ import annotations

import hashlib
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import platformdirs

from millctl.config.loader import LoadedConfig, packaged_file

APP = "millctl"
SOCKET_NAME = "millctl.sock"
SYSTEM_RUNTIME_DIR = Path("/run") / APP
SYSTEM_STATE_DIR = Path("/var/lib") / APP


def _env_dir(name: str) -> Path | None:
    """The first directory of a (possibly colon-separated, as systemd writes it) environment variable."""
    value = os.environ.get(name, "").split(":")[0].strip()
    return Path(value) if value and os.path.isabs(value) else None


def _platform_dirs() -> platformdirs.PlatformDirs:
    return platformdirs.PlatformDirs(APP, appauthor=False)


def runtime_dir() -> Path:
    """The folder of the service socket by convention (see the module docstring)."""
    systemd = _env_dir("RUNTIME_DIRECTORY")
    if systemd is not None:
        return systemd
    with warnings.catch_warnings():  # "XDG_RUNTIME_DIR is not set, falling back to …": the fallback is documented
        warnings.simplefilter("ignore")
        return Path(_platform_dirs().user_runtime_dir)


def state_dir() -> Path:
    """The folder of the records by convention (see the module docstring)."""
    systemd = _env_dir("STATE_DIRECTORY")
    if systemd is not None:
        return systemd
    return Path(_platform_dirs().user_state_dir)


def instance_name(loaded: LoadedConfig) -> str | None:
    """The per-configuration folder name under the user conventions (None: the packaged default, or systemd).

    ``<file stem>-<8 hex of the config file's absolute path>``: one clone's ``config/mill.toml`` is not
    another's. Under systemd the unit is the one instance, in its own folders.
    """
    if _env_dir("RUNTIME_DIRECTORY") is not None or _env_dir("STATE_DIRECTORY") is not None:
        return None
    source = Path(loaded.source).resolve()
    if source == packaged_file("mill.toml").resolve():
        return None
    return f"{source.stem}-{hashlib.sha256(str(source).encode()).hexdigest()[:8]}"


def ensure_private_dir(path: Path, mode: int = 0o750) -> None:
    """Create ``path`` and every missing parent with ``mode`` (whatever the umask), as the service's folders."""
    missing = []
    for folder in (path, *path.parents):
        if folder.exists():
            break
        missing.append(folder)
    for folder in reversed(missing):
        folder.mkdir(mode=mode, exist_ok=True)
        folder.chmod(mode)


def _from_config(value: str, loaded: LoadedConfig) -> Path:
    """A configured path; a relative one from the config file's folder."""
    path = Path(value).expanduser()
    return path if path.is_absolute() else Path(loaded.source).resolve().parent / path


def _conventional(base: Path, loaded: LoadedConfig) -> Path:
    instance = instance_name(loaded)
    return base / instance if instance else base


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
        socket, socket_from = _conventional(runtime_dir(), loaded) / SOCKET_NAME, "convention"
    records = _from_config(service.records_dir, loaded) if service.records_dir else (
        _conventional(state_dir(), loaded) / "records")
    return ServicePaths(socket=socket, records_dir=records, socket_from=socket_from)


__all__ = [
    "SOCKET_NAME",
    "SYSTEM_RUNTIME_DIR",
    "SYSTEM_STATE_DIR",
    "ServicePaths",
    "ensure_private_dir",
    "instance_name",
    "runtime_dir",
    "service_paths",
    "state_dir",
]

"""Convert a bus log between formats with python-can's readers and writers (what ``python -m can.logconvert`` does).

The service writes candump ``.log``; SavvyCAN, CANalyzer/CANoe, PCAN-View and
asammdf read ``.asc``, ``.blf``, ``.trc`` and ``.mf4``. Direction (Tx/Rx) and
the channel name go across with every frame. ``.mf4`` needs asammdf, the
optional extra ``millctl[mf4]``.
"""

from __future__ import annotations

from pathlib import Path

import can

from millctl.errors import InvalidInputError

READ_SUFFIXES = (".log", ".asc", ".blf", ".trc", ".csv", ".mf4")
WRITE_SUFFIXES = (".log", ".asc", ".blf", ".trc", ".csv", ".mf4")


def _suffix(path: Path, allowed: tuple[str, ...], what: str) -> str:
    suffix = path.suffix.lower()
    if suffix not in allowed:
        raise InvalidInputError(f"{what} {path}: format {suffix or '(none)'} is not one of {', '.join(allowed)}")
    return suffix


def convert_log(source: Path, target: Path) -> int:
    """Write every frame of ``source`` to ``target`` (formats by suffix); return the number of frames."""
    _suffix(source, READ_SUFFIXES, "bus log")
    if _suffix(target, WRITE_SUFFIXES, "output") == ".mf4" or source.suffix.lower() == ".mf4":
        import importlib.util

        if importlib.util.find_spec("asammdf") is None:
            raise InvalidInputError("MF4 needs asammdf: install the optional extra (pip install 'millctl[mf4]')")
    if not source.is_file():
        raise InvalidInputError(f"bus log {source}: no such file")
    if target.exists():
        raise InvalidInputError(f"output {target} exists: refusing to overwrite it")
    count = 0
    try:
        with can.LogReader(source) as reader, can.Logger(target) as writer:
            for message in reader:
                writer.on_message_received(message)
                count += 1
    except (ValueError, OSError) as exc:
        target.unlink(missing_ok=True)
        raise InvalidInputError(f"bus log {source}: cannot convert to {target}: {exc}") from None
    return count


__all__ = ["READ_SUFFIXES", "WRITE_SUFFIXES", "convert_log"]

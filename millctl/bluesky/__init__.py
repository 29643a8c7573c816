"""The mill in the lab's orchestration: ophyd-async devices and bluesky plans over ``millctl serve`` (issue 38).

Needs the optional extra: ``pip install millctl[bluesky]`` (bluesky, ophyd-async). The core package never
imports this one. ::

    from bluesky import RunEngine
    from ophyd_async.plan_stubs import ensure_connected
    from millctl.bluesky import Mill, SuspendWhenMillNotReady
    from millctl.bluesky.plans import mill_at

    RE = RunEngine()
    mill = Mill(name="mill")                    # the service socket of the config, as every client finds it
    RE(ensure_connected(mill))
    RE.install_suspender(SuspendWhenMillNotReady(mill))
    RE(mill_at(mill, 150.0, 800.0, duration_s=600.0, detectors=[xrd]))

Everything goes through the service's API with the device's control lease: the interlock, the lease and the
records apply as to every other client (docs/bluesky.md).
"""

from __future__ import annotations

try:
    import bluesky  # noqa: F401
    import ophyd_async  # noqa: F401
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError(f"millctl.bluesky needs the optional extra: pip install 'millctl[bluesky]' ({exc})") from exc

from millctl.bluesky.devices import Axis, Mill, MillPoint
from millctl.bluesky.link import MillTripped, MoveInterrupted, Readiness, Settle, readiness
from millctl.bluesky.suspenders import SuspendWhenMillNotReady

__all__ = ["Axis", "Mill", "MillPoint", "MillTripped", "MoveInterrupted", "Readiness", "Settle",
           "SuspendWhenMillNotReady", "readiness"]

"""millctl: control and test-bench software for a horizontal vibratory rod mill.

The physics comes from the paper in ``shared/paper/rod-mill-paper.txt``; the
interlock that keeps the mill inside the eq. 9 detachment envelope lives in
:mod:`millctl.safety`.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("millctl")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

__all__ = ["__version__"]

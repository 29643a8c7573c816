"""``python -m bench``: see :mod:`bench.cli`; at a lower CPU priority unless ``--no-nice`` (millctl.cli.priority)."""

import sys

from bench.cli import main
from millctl.cli.priority import NO_NICE_FLAG, lower_priority

argv = sys.argv[1:]
lower_priority(NO_NICE_FLAG in argv, "the benchmarks")
sys.exit(main([arg for arg in argv if arg != NO_NICE_FLAG]))

"""millctl's benchmarks (issue 11): speed against error, the cost of each level of detail, safety timing.

Run ``python -m bench`` (``--quick`` for a smoke run); every figure in
docs/benchmarks.md is produced by :mod:`bench.report` from the JSON this writes.
Each speed figure is a ratio against a baseline measured in the same run, so
the numbers stay comparable on a shared, loaded machine.
"""

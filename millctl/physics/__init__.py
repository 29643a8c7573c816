"""The paper's physics as pure numpy/scipy functions (no I/O, no CAN).

Modules: :mod:`.limits` (detachment limits, the interlock's closed forms).
"""

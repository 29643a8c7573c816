"""The controller service starts without the compiled physics.

The interlock is closed forms (docs/model.md, level (a)); numba and scipy are
the node's and the planner's. Loading them with the service cost about half of
its start-up on the host and a minute a process in the VM tier (tests/vm/README.md),
so the service's modules must import them only where a plan is made.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

COMPILED_PHYSICS = ("numba", "scipy", "millctl.physics.kernels", "millctl.physics.telemetry")


def _loaded_after(statement: str) -> list[str]:
    probe = (
        f"import json, sys\n{statement}\nprint(json.dumps(sorted(m for m in {COMPILED_PHYSICS!r} if m in sys.modules)))"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True)
    return list(json.loads(done.stdout.strip().splitlines()[-1]))


def test_the_service_side_imports_no_compiled_physics() -> None:
    # One interpreter for the three: none of them may load any of COMPILED_PHYSICS.
    assert _loaded_after("import millctl.service.server, millctl.recipes.runner, millctl.safety") == []


def test_a_recipe_plan_loads_the_physics_it_needs() -> None:
    statement = (
        "from millctl.config import load_config\n"
        "from millctl.recipes import load_recipe, plan_recipe\n"
        "plan = plan_recipe(load_recipe('config/recipes/demo.toml').recipe, load_config('config/mill.toml').config)\n"
        "assert plan.ok and plan.total_dose_kj_g > 0, plan"
    )
    assert _loaded_after(statement) == sorted(COMPILED_PHYSICS)


def test_the_package_still_re_exports_its_names() -> None:
    import millctl.physics as physics
    from millctl.physics.telemetry import revolution_summary

    assert physics.revolution_summary is revolution_summary
    with pytest.raises(AttributeError, match="no attribute 'nonesuch'"):
        _ = physics.nonesuch

"""What loads the compiled physics (numba, scipy), and when.

The interlock and the controller are closed forms (docs/model.md, level (a)) and
must not load it; nor must the command line before a command needs it (every
``millctl`` process, and each one a test starts, would pay for importing them).
The service does load it, at start, through the recipe planner: planning a recipe
is a request under the caller's lease, and a first plan that had to import numba
and scipy took longer than the 30 s lease in the VM tier (ci6,
tests/hil/test_stop_race.py on socketcan), so the import is paid before any request.
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


def test_the_interlock_the_controller_and_the_command_line_import_no_compiled_physics() -> None:
    statement = "import millctl.safety, millctl.controller, millctl.cli\nmillctl.cli.build_parser()"
    assert _loaded_after(statement) == []


def test_the_service_loads_the_planners_physics_at_start() -> None:
    assert _loaded_after("import millctl.service.server") == sorted(COMPILED_PHYSICS)


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

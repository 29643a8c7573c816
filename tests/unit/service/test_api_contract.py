"""The one typed contract (millctl.api): defined once, used by the service, documented in its OpenAPI schema."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import millctl.controller
import millctl.recipes.runner
from millctl import api
from millctl.config import load_config
from millctl.service import ServiceRuntime, create_app
from tests.support.service import write_config


def test_status_model_mirrors_the_controller_status_field_for_field() -> None:
    assert list(api.StatusOut.model_fields) == [f.name for f in fields(millctl.controller.Status)]


def test_state_and_event_enums_are_defined_once_in_the_api() -> None:
    assert millctl.controller.ControllerState is api.ControllerState
    assert millctl.controller.EventKind is api.EventKind
    assert millctl.recipes.runner.RunState is api.RunState
    assert {api.RunState.DONE, api.RunState.ABORTED, api.RunState.FAILED} == millctl.recipes.runner.FINAL


def _spec(tmp_path: Path) -> dict[str, object]:
    runtime = ServiceRuntime(load_config(write_config(tmp_path)), embed_node=False)
    try:
        return create_app(runtime).openapi()
    finally:
        runtime.close()


def test_openapi_states_and_codes_are_enums_and_fields_are_described(tmp_path: Path) -> None:
    schemas = _spec(tmp_path)["components"]["schemas"]  # type: ignore[index]
    assert schemas["ControllerState"]["enum"] == [s.value for s in api.ControllerState]
    assert schemas["RunState"]["enum"] == [s.value for s in api.RunState]
    assert schemas["ErrorCode"]["enum"] == [c.value for c in api.ErrorCode]
    assert schemas["EventKind"]["enum"] == [k.value for k in api.EventKind]
    undescribed = [
        name
        for name, prop in schemas["StatusOut"]["properties"].items()
        if "description" not in prop and "$ref" not in prop and "allOf" not in prop
        and name not in ("state", "heater_on", "detached")
    ]
    assert undescribed == []


def test_recipe_progress_is_a_model_not_a_dict(tmp_path: Path) -> None:
    schemas = _spec(tmp_path)["components"]["schemas"]  # type: ignore[index]
    progress = schemas["RecipeOut"]["properties"]["progress"]
    assert {"$ref": "#/components/schemas/RecipeProgress"} in progress["anyOf"]

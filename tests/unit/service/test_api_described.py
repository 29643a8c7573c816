"""Every field of the API says what it is: the OpenAPI schema's, and the event stream's own schema (issue 39, 7)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema_rs

from millctl.api import ControllerState, EventKind, EventOut
from millctl.api.stream_schema import stream_schema
from millctl.config import load_config
from millctl.service import ServiceRuntime, create_app
from tests.support.service import write_config

REPO = Path(__file__).resolve().parents[3]


def _undescribed(schemas: dict[str, Any]) -> list[str]:
    return [f"{name}.{field}" for name, schema in schemas.items()
            for field, prop in (schema.get("properties") or {}).items() if "description" not in prop]


def test_every_openapi_field_has_a_description(tmp_path: Path) -> None:
    runtime = ServiceRuntime(load_config(write_config(tmp_path)))
    try:
        schemas = create_app(runtime).openapi()["components"]["schemas"]
    finally:
        runtime.shutdown()
    assert _undescribed(schemas) == []


def test_the_event_stream_has_a_schema_in_the_docs_matching_the_models() -> None:
    committed = json.loads((REPO / "docs" / "event-stream.schema.json").read_text())
    assert committed == json.loads(json.dumps(stream_schema())), "python -m millctl.api.stream_schema > docs/…"
    assert _undescribed(committed["$defs"]) == []
    validator = jsonschema_rs.validator_for(committed)
    event = EventOut(seq=7, t=1.0, time_s=0.5, kind=EventKind.STATE, source="controller", message="ARMED", data={})
    assert validator.is_valid({"event": "event", "id": "7", "data": event.model_dump(mode="json")})
    assert not validator.is_valid({"event": "event", "data": event.model_dump(mode="json")})  # an event has an id
    assert not validator.is_valid({"event": "status", "data": event.model_dump(mode="json")})
    assert ControllerState.ARMED.value in json.dumps(committed)  # the states are spelt out
    assert "#the-event-stream" in committed["description"]
    assert "### The event stream" in (REPO / "docs" / "operations.md").read_text()

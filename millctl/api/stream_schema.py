"""The schema of the event stream (``GET /v1/stream``), which OpenAPI cannot describe: SSE events and their data.

Each server-sent event has an ``event`` name (:class:`~millctl.api.enums.StreamKind`)
and JSON ``data``: ``status`` carries a :class:`~millctl.api.models.StatusOut`
(every 0.25 s, no ``id``), ``event`` an :class:`~millctl.api.models.EventOut`
(as it happens, ``id`` = its ``seq``, which a reconnecting client sends back as
``Last-Event-ID``). :func:`stream_schema` is that contract as one JSON Schema
document (draft 2020-12), written to docs/event-stream.schema.json by
``python -m millctl.api.stream_schema`` and held to the models by a unit test.
"""

from __future__ import annotations

import json
import sys
from typing import Any

from pydantic import BaseModel
from pydantic.json_schema import models_json_schema

from millctl.api.enums import StreamKind
from millctl.api.models import EventOut, StatusOut

PAYLOADS: dict[StreamKind, type[BaseModel]] = {StreamKind.STATUS: StatusOut, StreamKind.EVENT: EventOut}
"""Each SSE event name and the model of its JSON data."""


def stream_schema() -> dict[str, Any]:
    """One server-sent event of ``GET /v1/stream``: its name, its id, and its data by name (JSON Schema)."""
    _, defs = models_json_schema([(model, "serialization") for model in PAYLOADS.values()],
                                 ref_template="#/$defs/{model}")
    variants = []
    for kind, model in PAYLOADS.items():
        with_id = kind is StreamKind.EVENT
        variants.append({
            "type": "object",
            "description": f"SSE `event: {kind.value}`: data is one {model.__name__} as JSON"
            + ("; `id` is the event's seq (send it back as Last-Event-ID to resume)" if with_id else "; no id"),
            "properties": {
                "event": {"const": kind.value, "description": "the SSE event name"},
                "id": ({"type": "string", "pattern": "^[0-9]+$", "description": "the event's seq, as text"}
                       if with_id else {"type": "null", "description": "status items carry no id"}),
                "data": {"$ref": f"#/$defs/{model.__name__}", "description": f"the {model.__name__} as JSON"},
            },
            "required": ["event", "data", *(["id"] if with_id else [])],
            "additionalProperties": False,
        })
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "millctl event stream (GET /v1/stream): one server-sent event",
        "description": "text/event-stream; each SSE event is `event`, optional `id` and one line of JSON `data`. "
        "status every 0.25 s, event as each happens; ?count=N ends after N items. docs/operations.md#the-event-stream",
        "oneOf": variants,
        "$defs": defs["$defs"],
    }


def main() -> None:
    """Print the schema (``python -m millctl.api.stream_schema > docs/event-stream.schema.json``)."""
    json.dump(stream_schema(), sys.stdout, indent=2, ensure_ascii=False)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()

__all__ = ["PAYLOADS", "stream_schema"]

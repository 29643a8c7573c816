"""JSON-lines records: complete lines, rotation, and a torn tail."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from millctl.records import RecordWriter, read_records


def test_each_record_is_one_parseable_line(tmp_path: Path) -> None:
    writer = RecordWriter(tmp_path, "events")
    for i in range(3):
        writer.write({"kind": "state", "i": i, "reason": "ünïcode ok"})
    lines = writer.path.read_text().splitlines()
    assert [json.loads(line)["i"] for line in lines] == [0, 1, 2]
    assert all("t" in json.loads(line) for line in lines)
    writer.close()


def test_rotation_keeps_the_newest(tmp_path: Path) -> None:
    writer = RecordWriter(tmp_path, "events", rotate_bytes=1024, keep=2, sync=False)
    for i in range(200):
        writer.write({"i": i, "pad": "x" * 40})
    writer.close()
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == ["events.1.jsonl", "events.2.jsonl", "events.jsonl"]
    newest = [r["i"] for r in read_records(tmp_path / "events.jsonl")]
    assert newest[-1] == 199
    previous = [r["i"] for r in read_records(tmp_path / "events.1.jsonl")]
    assert previous[-1] + 1 == newest[0]


def test_torn_last_line_is_skipped_but_corruption_inside_is_not(tmp_path: Path) -> None:
    path = tmp_path / "r.jsonl"
    path.write_text('{"a": 1}\n{"a": 2}\n{"a": 3, "b"')
    assert [r["a"] for r in read_records(path)] == [1, 2]
    path.write_text('{"a": 1}\nnot json\n{"a": 3}\n')
    with pytest.raises(json.JSONDecodeError):
        list(read_records(path))

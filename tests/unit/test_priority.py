"""Studies and benchmarks run below the mill's control loop unless told not to (SAFETY 27, issue 37 item 7)."""

from __future__ import annotations

import os

import pytest

from millctl.cli import build_parser, priority
from millctl.cli.priority import BACKGROUND_NICE, lower_priority


def test_background_work_raises_its_niceness_unless_it_opts_out(monkeypatch: pytest.MonkeyPatch) -> None:
    asked: list[int] = []

    def nice(increment: int) -> int:
        asked.append(increment)
        return 10 + increment

    monkeypatch.setattr(os, "nice", nice)
    assert lower_priority(False, "the study") == 10 + BACKGROUND_NICE
    assert lower_priority(True, "the study") is None
    assert asked == [BACKGROUND_NICE]


def test_a_process_that_may_not_lower_its_priority_runs_anyway(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    def refused(increment: int) -> int:
        raise PermissionError("not permitted")

    monkeypatch.setattr(os, "nice", refused)
    assert lower_priority(False, "the benchmarks") is None
    assert "cannot lower the CPU priority" in caplog.text


@pytest.mark.parametrize("argv", [["study", "s.toml"], ["bench"]])
def test_the_study_and_bench_commands_take_no_nice(argv: list[str]) -> None:
    parser = build_parser()
    assert parser.parse_args(argv).no_nice is False
    assert parser.parse_args([*argv, priority.NO_NICE_FLAG]).no_nice is True

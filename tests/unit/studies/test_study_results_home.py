"""A study without --out keeps its results in the user's state folder, not in the working folder (issue 39, 8)."""

from __future__ import annotations

from pathlib import Path

import pytest

from millctl.cli import main
from tests.conftest import CONFIG_FILE


def test_no_results_file_is_left_in_the_working_folder(grid_file: Path, tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    monkeypatch.delenv("STATE_DIRECTORY", raising=False)
    assert main(["--config", str(CONFIG_FILE), "study", str(grid_file), "--workers", "1"]) == 0
    assert list(work.iterdir()) == []
    results = tmp_path / "state" / "millctl" / "studies" / "grid.parquet"
    assert results.is_file()
    assert str(results) in capsys.readouterr().err  # the summary says where the results are

"""mutmut's verdicts outlive mutants/; a function changed since is judged again (support/mutation_verdicts.py)."""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from mutmut.configuration import reset_config

from tests.support import mutation_verdicts as mv

SOURCE = """\
def add(a, b):
    return a + b


class Gate:
    def open(self, x):
        return x > 3
"""

SETTING: dict[str, object] = {"mutmut": "3.8.1", "config": {"test_selection": "abc"}}


@pytest.fixture
def project(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A one-module project that mutmut mutates, as the working directory (mutmut reads its pyproject.toml)."""
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "__init__.py").write_text("")
    (tmp_path / "pkg" / "m.py").write_text(SOURCE)
    (tmp_path / "pyproject.toml").write_text('[tool.mutmut]\nsource_paths = ["pkg"]\n')
    monkeypatch.chdir(tmp_path)
    reset_config()
    yield tmp_path
    reset_config()


def make_mutants() -> dict[str, int | None]:
    """What ``mutmut run`` does first: make pkg/m.py's mutants, keeping the verdicts of unchanged functions."""
    from mutmut.__main__ import create_mutants_for_file

    Path("mutants/pkg").mkdir(parents=True, exist_ok=True)
    result = create_mutants_for_file(Path("pkg/m.py"), Path("mutants/pkg/m.py"))
    assert result.error is None
    return codes()


def codes() -> dict[str, int | None]:
    data: dict[str, int | None] = json.loads(Path("mutants/pkg/m.py.meta").read_text())["exit_code_by_key"]
    return data


def judge(verdicts: dict[str, int | None]) -> None:
    """Set verdicts in mutants/ as a mutmut run would."""
    meta = Path("mutants/pkg/m.py.meta")
    data = json.loads(meta.read_text())
    data["exit_code_by_key"].update(verdicts)
    meta.write_text(json.dumps(data))


ADD_1, OPEN_1, OPEN_2 = "pkg.m.x_add__mutmut_1", "pkg.m.xǁGateǁopen__mutmut_1", "pkg.m.xǁGateǁopen__mutmut_2"


def test_verdicts_saved_come_back_into_a_new_mutants_directory(project: Path) -> None:
    assert make_mutants() == {ADD_1: None, OPEN_1: None, OPEN_2: None}
    judge({ADD_1: 1, OPEN_1: 0, OPEN_2: 33})
    store = project / "verdicts.json"

    assert mv.save(Path("mutants"), store, SETTING) == 2  # "no tests" (33) is mutmut's to give again
    shutil.rmtree("mutants")
    assert mv.restore(Path("mutants"), store, SETTING) == 2

    assert make_mutants() == {ADD_1: 1, OPEN_1: 0, OPEN_2: None}


def test_a_function_changed_since_its_verdicts_is_judged_again(project: Path) -> None:
    make_mutants()
    judge({ADD_1: 1, OPEN_1: 0, OPEN_2: 1})
    store = project / "verdicts.json"
    mv.save(Path("mutants"), store, SETTING)
    shutil.rmtree("mutants")
    (project / "pkg" / "m.py").write_text(SOURCE.replace("x > 3", "x > 4"))

    mv.restore(Path("mutants"), store, SETTING)

    assert make_mutants() == {ADD_1: 1, OPEN_1: None, OPEN_2: None}


def test_restore_fills_only_what_mutants_has_no_verdict_for_in_the_same_function(project: Path) -> None:
    make_mutants()
    judge({ADD_1: 1, OPEN_1: 0, OPEN_2: 1})
    store = project / "verdicts.json"
    mv.save(Path("mutants"), store, SETTING)
    judge({ADD_1: 0, OPEN_1: None})  # mutants/ judged add's mutant again since; open's first has no verdict

    assert mv.restore(Path("mutants"), store, SETTING) == 1

    assert codes() == {ADD_1: 0, OPEN_1: 0, OPEN_2: 1}


def test_saving_again_keeps_the_stored_verdicts_of_unchanged_functions_and_drops_those_of_changed_ones(
    project: Path,
) -> None:
    make_mutants()
    judge({ADD_1: 1, OPEN_1: 0})
    store = project / "verdicts.json"
    mv.save(Path("mutants"), store, SETTING)
    shutil.rmtree("mutants")
    (project / "pkg" / "m.py").write_text(SOURCE.replace("x > 3", "x > 4"))
    make_mutants()  # a new mutants/, nothing restored: open changed, add has no verdict here
    judge({OPEN_2: 1})

    assert mv.save(Path("mutants"), store, SETTING) == 2

    files = json.loads(store.read_text())["files"]
    assert files["pkg/m.py"]["x_add"]["verdicts"] == {"1": 1}
    assert files["pkg/m.py"]["xǁGateǁopen"]["verdicts"] == {"2": 1}


def test_verdicts_given_under_another_mutmut_or_configuration_are_not_restored(
    project: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    make_mutants()
    judge({ADD_1: 1})
    store = project / "verdicts.json"
    mv.save(Path("mutants"), store, SETTING)
    shutil.rmtree("mutants")

    other: dict[str, object] = {"mutmut": "3.8.1", "config": {"test_selection": "def"}}
    assert mv.restore(Path("mutants"), store, other) == 0
    assert "restored nothing" in capsys.readouterr().err
    assert make_mutants() == {ADD_1: None, OPEN_1: None, OPEN_2: None}

    # and saving under the new setting starts the file afresh
    judge({OPEN_1: 0})
    assert mv.save(Path("mutants"), store, other) == 1

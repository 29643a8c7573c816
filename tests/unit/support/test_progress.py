"""How far a cut run got (tests/support/progress.py): the vcan tier's closing line when its VM is stopped."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.progress import Progress, ProgressLogError, cut_line, main, read_progress

LOG = """collected 5
start 18:38:12 tests/hil/test_a.py::test_one[socketcan]
passed 18:41:02 tests/hil/test_a.py::test_one[socketcan]
start 18:41:02 tests/hil/test_a.py::test_two[socketcan]
failed 18:43:40 tests/hil/test_a.py::test_two[socketcan]
start 18:43:40 tests/hil/test_b.py::test_three[socketcan]
error 18:45:00 tests/hil/test_b.py::test_three[socketcan]
start 18:45:00 tests/hil/test_b.py::test_four[socketcan - slow case]
"""


def test_a_log_cut_mid_test_counts_each_outcome_and_names_the_test_it_was_in() -> None:
    progress = read_progress(LOG)
    assert progress.collected == 5
    assert dict(progress.outcomes) == {"passed": 1, "failed": 1, "error": 1}
    assert progress.running == "tests/hil/test_b.py::test_four[socketcan - slow case]"
    assert cut_line("vcan", progress, "the VM's timeout, 4176 s") == (
        "vcan: FAILED: cut (the VM's timeout, 4176 s) after 3 of 5 cases: 1 passed, 1 failed, 1 errors, 0 skipped; "
        "in tests/hil/test_b.py::test_four[socketcan - slow case]; 1 not started"
    )


def test_a_log_cut_between_tests_names_no_test() -> None:
    text = (
        "collected 3\nstart 10:00:00 t.py::a\nskipped 10:00:01 t.py::a\n"
        "start 10:00:01 t.py::b\nxfailed 10:00:02 t.py::b\n"
    )
    assert cut_line("vcan", read_progress(text), "vng exit status 1") == (
        "vcan: FAILED: cut (vng exit status 1) after 2 of 3 cases: 0 passed, 0 failed, 0 errors, 1 skipped "
        "(1 xfailed); 1 not started"
    )


def test_an_empty_log_means_pytest_never_collected() -> None:
    assert read_progress("") == Progress(None)
    assert cut_line("vcan", read_progress(""), "the VM's timeout, 60 s") == (
        "vcan: FAILED: cut (the VM's timeout, 60 s) before pytest had collected its tests"
    )
    assert cut_line("vcan", read_progress("collected 32\n"), "x") == (
        "vcan: FAILED: cut (x) after 0 of 32 cases: 0 passed, 0 failed, 0 errors, 0 skipped; 32 not started"
    )


@pytest.mark.parametrize(
    ("line", "says"),
    [
        ("finished 10:00:00 t.py::a", "unknown word 'finished'"),
        ("passed", "is not 'collected N'"),
        ("collected many", "is not 'collected N'"),
    ],
)
def test_a_line_of_another_kind_is_refused_with_its_number(line: str, says: str) -> None:
    with pytest.raises(ProgressLogError, match="line 2") as refused:
        read_progress(f"collected 1\n{line}\n", "runs/vcan/progress.log")
    assert says in str(refused.value) and "runs/vcan/progress.log" in str(refused.value)


def test_the_command_prints_the_line_and_refuses_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "progress.log"
    log.write_text(LOG)
    assert main(["vcan", str(log), "the VM's timeout, 4176 s"]) == 0
    assert capsys.readouterr().out.startswith("vcan: FAILED: cut (the VM's timeout, 4176 s) after 3 of 5 cases")
    assert main(["vcan", str(tmp_path / "missing.log"), "x"]) == 0  # no log: the VM never reached pytest
    assert capsys.readouterr().out == "vcan: FAILED: cut (x) before pytest had collected its tests\n"
    log.write_text("collected 1\nbogus 10:00:00 t.py::a\n")
    assert main(["vcan", str(log), "x"]) == 1
    assert "unknown word 'bogus'" in capsys.readouterr().err
    assert main(["vcan"]) == 2
    assert "usage:" in capsys.readouterr().err

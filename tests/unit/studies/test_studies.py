"""Grid and optimiser studies on Set A: results, constraints, backends, resume."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest

from millctl.config import MillConfig
from millctl.studies import (
    DaskBackend,
    LocalBackend,
    ResultsStore,
    SerialBackend,
    StudyError,
    StudyRunner,
    check_parameters,
    load_study,
    pareto_front,
)
from millctl.studies.backends import Backend
from millctl.studies.run import StudyResult, grid_points
from tests.unit.studies.conftest import write


def same_rows(a: Sequence[dict[str, Any]], b: Sequence[dict[str, Any]]) -> None:
    """Equal point for point: every column, NaN equal to NaN, floats bit for bit."""
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x.keys() == y.keys()
        for k in x:
            both_nan = isinstance(x[k], float) and math.isnan(x[k]) and math.isnan(y[k])
            assert both_nan or x[k] == y[k], (k, x[k], y[k])


def run(
    path: Path,
    config: MillConfig,
    backend: Backend | None = None,
    store: ResultsStore | None = None,
    batch_size: int | None = None,
) -> StudyResult:
    study = load_study(path)
    check_parameters(study, config, str(path))
    runner = StudyRunner(study, config, str(path), batch_size=batch_size)
    if store is not None:
        store.fingerprint = runner.fingerprint
        store.resume()
        runner.store = store
    return runner.run(backend or SerialBackend())


def test_grid_study_on_set_a(grid_file: Path, config: MillConfig) -> None:
    result = run(grid_file, config)
    assert [(r["rotary_rpm"], r["vibration_rpm"]) for r in result.rows] == [
        (80.0, 400.0), (80.0, 800.0), (180.0, 400.0), (180.0, 800.0), (280.0, 400.0), (280.0, 800.0),
    ]  # fmt: skip
    # 280 rpm is above the corrected best-phase limit (minus the 5 % margin) at 400 rpm: infeasible, with the reason
    outside = result.rows[4]
    assert not outside["feasible"] and "corrected-best-phase" in outside["violations"]
    assert outside["margin_corrected_best_phase_rpm"] < 0.0
    best = result.best
    assert best is not None and best["feasible"]
    feasible = [r for r in result.rows if r["feasible"]]
    assert best["objective"] == max(r["dose_rate_j_g_s"] for r in feasible)
    # the dose rate is the milling power per gram of the configured powder charge
    assert best["dose_rate_j_g_s"] == pytest.approx(best["milling_power_w"] / config.mill.powder.charge_g)
    assert all(r["events"] > 0 for r in feasible)


def test_optimiser_study_on_set_a(optimiser_file: Path, config: MillConfig) -> None:
    first = run(optimiser_file, config)
    again = run(optimiser_file, config)
    same_rows(first.rows, again.rows)  # seeded: the same points in the same order
    assert len(first.rows) >= 8
    best = first.best
    assert best is not None and best["feasible"]
    assert best["objective"] == max(r["objective"] for r in first.rows if r["feasible"])
    assert 60.0 <= best["rotary_rpm"] <= 300.0


def test_backends_give_identical_results(grid_file: Path, config: MillConfig) -> None:
    serial = run(grid_file, config, SerialBackend())
    local = LocalBackend(2)
    try:
        two = run(grid_file, config, local, batch_size=1)
    finally:
        local.close()
    same_rows(serial.rows, two.rows)
    from distributed import Client, LocalCluster

    with (
        LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster,
        Client(cluster) as client,
    ):
        dask = run(grid_file, config, DaskBackend(client=client), batch_size=2)
    same_rows(serial.rows, dask.rows)


class Interrupt(Exception):
    pass


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_resume_after_interruption(grid_file: Path, config: MillConfig, tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"results{suffix}"
    study = load_study(grid_file)
    runner = StudyRunner(study, config, str(grid_file), batch_size=2)
    runner.store = ResultsStore(path, runner.fingerprint)

    def stop_after_first_batch(done: int, total: int) -> None:
        if done >= 2:
            raise Interrupt

    with pytest.raises(Interrupt):
        runner.run(SerialBackend(), stop_after_first_batch)
    store = ResultsStore(path, runner.fingerprint)
    assert store.resume() == 2
    resumed = StudyRunner(study, config, str(grid_file), store=store).run(SerialBackend())
    assert resumed.computed == 4 and resumed.reused == 2
    fresh = run(grid_file, config)
    same_rows(fresh.rows, resumed.rows)


def test_csv_drops_a_cut_off_last_row(grid_file: Path, config: MillConfig, tmp_path: Path) -> None:
    path = tmp_path / "r.csv"
    store = ResultsStore(path, "x")
    result = run(grid_file, config, store=store)
    text = path.read_text()
    path.write_text(text[: -len(text.splitlines()[-1]) // 2 - 1])  # half of the last row, no newline
    again = ResultsStore(path, store.fingerprint)
    assert again.resume() == len(result.rows) - 1


def test_results_of_another_study_are_refused(
    grid_file: Path, optimiser_file: Path, config: MillConfig, tmp_path: Path
) -> None:
    path = tmp_path / "r.parquet"
    run(grid_file, config, store=ResultsStore(path, "x"))
    with pytest.raises(Exception, match="another study"):
        run(optimiser_file, config, store=ResultsStore(path, "x"))


def test_pareto_front_keeps_only_undominated_points() -> None:
    rows = [
        {"point": 0, "feasible": True, "a": 1.0, "b": 5.0},
        {"point": 1, "feasible": True, "a": 2.0, "b": 4.0},
        {"point": 2, "feasible": True, "a": 1.5, "b": 3.0},  # dominated by 1
        {"point": 3, "feasible": False, "a": 9.0, "b": 9.0},  # infeasible
    ]
    assert [r["point"] for r in pareto_front(rows, ["a", "b"])] == [0, 1]
    assert [r["point"] for r in pareto_front(rows, ["a", "-b"])] == [2, 1]  # 0 is beaten by 1 on both


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ('[study]\nname = "x"\nspeed = 3\n', "study.speed: unknown key"),
        (
            '[study]\nname = "x"\n[parameters.rotary_rpm]\nvalues = [1]\ngrid = { start = 1, stop = 2, num = 2 }\n'
            '[objective]\nmaximize = "gamma"\n',
            "give exactly one of grid, values, bounds",
        ),
        (
            '[study]\nname = "x"\n[parameters.rotary_rpm]\ngrid = { start = 1, stop = 2, num = 0 }\n'
            '[objective]\nmaximize = "gamma"\n',
            "parameters.rotary_rpm.grid.num = 0",
        ),
        (
            '[study]\nname = "x"\n[parameters.spring_n_per_m]\nvalues = [1]\n[parameters.rotary_rpm]\n'
            'bounds = [1, 2]\n[objective]\nmaximize = "gamma"\n',
            "gives bounds for every parameter",
        ),
    ],
)
def test_bad_study_files_name_file_field_and_value(tmp_path: Path, text: str, expected: str) -> None:
    path = write(tmp_path, "bad.toml", text)
    with pytest.raises(StudyError) as err:
        load_study(path)
    assert str(path) in str(err.value) and expected in str(err.value)


def test_unknown_metric_material_and_missing_speed(tmp_path: Path, config: MillConfig) -> None:
    text = (
        '[study]\nname = "x"\n[parameters.rotary_rpm]\nvalues = [100]\n[parameters.rod_material]\n'
        'values = ["unobtainium"]\n[metrics]\nnames = ["power"]\n[objective]\nmaximize = "gamma"\n'
    )
    path = write(tmp_path, "bad.toml", text)
    study = load_study(path)
    with pytest.raises(StudyError, match=r"unobtainium.*unknown") as err:
        check_parameters(study, config, str(path))
    assert "vibration_rpm: vary it" in str(err.value)
    with pytest.raises(StudyError, match="metrics power unknown"):
        StudyRunner(study, config, str(path))


def test_a_mill_that_cannot_exist_is_an_infeasible_point_with_its_reason(tmp_path: Path, config: MillConfig) -> None:
    text = (
        '[study]\nname = "x"\nrotary_rpm = 100\nvibration_rpm = 800\n[parameters.n_rods]\nvalues = [6, 10]\n'
        '[objective]\nmaximize = "milling_power_w"\n'
    )
    result = run(write(tmp_path, "s.toml", text), config)
    assert [r["n_rods"] for r in result.rows] == [6, 10]
    assert result.rows[0]["feasible"] and not result.rows[1]["feasible"]
    assert "packing limit" in result.rows[1]["violations"]


def test_grid_points_round_integer_parameters(tmp_path: Path, config: MillConfig) -> None:
    text = (
        '[study]\nname = "x"\nrotary_rpm = 100\nvibration_rpm = 800\n[parameters.n_rods]\n'
        'grid = { start = 2, stop = 4, num = 5 }\n[objective]\nmaximize = "gamma"\n'
    )
    points = grid_points(load_study(write(tmp_path, "s.toml", text)))
    assert [p["n_rods"] for p in points] == [2, 2, 3, 4, 4]


def test_a_study_without_a_results_file_writes_nothing(
    grid_file: Path, config: MillConfig, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    written = []
    monkeypatch.setattr("millctl.studies.store.write_atomically", lambda path, write: written.append(path))
    result = run(grid_file, config)
    assert len(result.rows) == 6 and written == [] and [p.name for p in tmp_path.iterdir()] == ["grid.toml"]


@pytest.mark.parametrize("kind", ["fifo", "directory"])
def test_results_are_never_renamed_over_a_pipe_or_a_directory(tmp_path: Path, kind: str) -> None:
    # A pipe or a directory made here, never a shared device: a regression must not replace /dev/null.
    import os

    from millctl.errors import InvalidInputError

    target = tmp_path / "results.parquet"
    if kind == "fifo":
        os.mkfifo(target)
    else:
        target.mkdir()
    with pytest.raises(InvalidInputError, match="not a regular file"):
        ResultsStore(target, "x")
    assert target.exists() and not target.is_file()


def test_a_study_over_both_models_resumes_from_its_csv(tmp_path: Path, config: MillConfig) -> None:
    text = """
[study]
name = "both models"
[parameters.variant]
values = ["paper", "corrected"]
[parameters.rotary_rpm]
values = [80.0, 180.0]
[parameters.vibration_rpm]
values = [800.0]
[metrics]
names = ["milling_power_w"]
cam_phases = 2
[objective]
maximize = "milling_power_w"
"""
    study_file = write(tmp_path, "variants.toml", text)
    path = tmp_path / "results.csv"
    store = ResultsStore(path, "x")
    first = run(study_file, config, store=store)
    assert {r["variant"] for r in first.rows} == {"paper", "corrected"}
    again = ResultsStore(path, store.fingerprint)
    assert again.resume() == len(first.rows) == 4
    resumed = run(study_file, config, store=again)
    assert resumed.reused == 4 and resumed.computed == 0
    same_rows(first.rows, resumed.rows)

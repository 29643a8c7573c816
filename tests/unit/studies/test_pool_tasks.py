"""Tasks of the worker pools: the runner's batches merged into fewer, larger tasks, kept whole and in order."""

from __future__ import annotations

from typing import Any

from millctl.config import MillConfig
from millctl.studies import Study, StudyRunner
from millctl.studies.backends import POOL_TASKS_PER_WORKER, batched, point_cost_s, pool_tasks
from millctl.studies.engine import PointTask
from millctl.studies.run import grid_points


def _batches(config: MillConfig, num: int, size: int, metrics: list[str]) -> list[list[PointTask]]:
    data: dict[str, Any] = {
        "study": {"name": "tasks", "variant": "corrected", "seed": 1},
        "parameters": {
            "rotary_rpm": {"grid": {"start": 120.0, "stop": 200.0, "num": num}},
            "vibration_rpm": {"grid": {"start": 400.0, "stop": 800.0, "num": num}},
        },
        "metrics": {"names": metrics, "revolutions": 1.0},
        "objective": {"maximize": metrics[0]},
    }
    study = Study.model_validate(data)
    runner = StudyRunner(study, config, "test")
    return batched([runner.task(p) for p in grid_points(study)], size)


def _flat(tasks: list[list[list[PointTask]]]) -> list[list[PointTask]]:
    return [batch for task in tasks for batch in task]


def test_small_level_c_batches_merge_into_tasks_of_the_least_work(config: MillConfig) -> None:
    batches = _batches(config, 40, 16, ["impact_energy_p90_j"])  # 1,600 points, 100 batches of 16
    tasks = pool_tasks(batches, workers=2, least_s=0.25)
    assert _flat(tasks) == batches  # every batch, whole, in the order the runner made them
    point_s = point_cost_s({"c"}, revolutions=1.0)
    work_s = [point_s * sum(len(b) for b in task) for task in tasks]
    assert min(work_s[:-1]) >= 0.25  # the last task takes what is left
    assert len(tasks) < len(batches) and len(tasks) >= POOL_TASKS_PER_WORKER * 2


def test_few_batches_are_not_merged_below_four_tasks_a_worker(config: MillConfig) -> None:
    batches = _batches(config, 4, 2, ["impact_energy_p90_j"])  # 16 points, 8 batches: far below 0.25 s of work
    tasks = pool_tasks(batches, workers=2, least_s=0.25)
    assert _flat(tasks) == batches
    assert len(tasks) == 8
    assert pool_tasks([], workers=2) == []

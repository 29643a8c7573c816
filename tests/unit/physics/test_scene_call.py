"""The public API's reused single-scene path gives the batch kernel's rows bit for bit."""

from __future__ import annotations

import dataclasses
import math
import threading
from typing import Any

import numpy as np
import pytest

from millctl.physics import kernels
from millctl.physics.agreement import random_scenes
from millctl.physics.model import MillModel


def _batch_row(scene, rods: str = "all") -> list[float] | None:  # type: ignore[no-untyped-def]
    row = kernels.first_impacts(kernels.scene_row(scene)[None, :], rods=rods, horizon_s=5.0)[0]
    return None if row[kernels.OUT.index("found")] != 1.0 else row.tolist()


def _same(a: list[float] | None, b: list[float] | None) -> bool:
    if a is None or b is None:
        return a is b
    return bool(np.array_equal(np.array(a), np.array(b), equal_nan=True))


def test_scene_call_is_the_batch_row_across_models(set_a_corrected: MillModel, set_a_paper: MillModel) -> None:
    call = kernels.SceneCall()
    scenes = random_scenes(set_a_corrected, 40, 5) + random_scenes(set_a_paper, 40, 6)
    few_rods = dataclasses.replace(set_a_corrected, n_rods=2)
    scenes += random_scenes(few_rods, 20, 7) + random_scenes(set_a_corrected, 10, 8)  # a model with fewer rods between
    for scene in scenes:
        assert _same(call.first_impact(scene), _batch_row(scene)), scene


def test_scene_call_one_rod_matches_the_batch(set_a_corrected: MillModel) -> None:
    call = kernels.SceneCall()
    for scene in random_scenes(set_a_corrected, 30, 9):
        mine = call.first_impact(scene, all_rods=False, horizon_s=math.inf, flight_cap_s=2.0)
        raw = kernels.first_impacts(kernels.scene_row(scene)[None, :], rods="one", horizon_s=math.inf, flight_cap_s=2.0)
        want = None if raw[0, kernels.OUT.index("found")] != 1.0 else raw[0].tolist()
        assert _same(mine, want), scene


def test_threads_do_not_share_the_work_arrays(set_a_corrected: MillModel) -> None:
    call = kernels.SceneCall()
    scenes = random_scenes(set_a_corrected, 60, 10)
    want = [_batch_row(s) for s in scenes]
    got: dict[int, list[list[float] | None]] = {}

    def run(k: int) -> None:
        got[k] = [call.first_impact(s) for s in (scenes if k % 2 == 0 else scenes[::-1])]

    threads = [threading.Thread(target=run, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k, rows in got.items():
        ordered = rows if k % 2 == 0 else rows[::-1]
        assert all(_same(a, b) for a, b in zip(ordered, want, strict=True))


def _counts(nrt: Any) -> tuple[int, int]:
    """numba's counts of arrays and array wrappers (meminfos) made and released so far."""
    made = nrt.memsys_get_stats_alloc() + nrt.memsys_get_stats_mi_alloc()
    return made, nrt.memsys_get_stats_free() + nrt.memsys_get_stats_mi_free()


def test_kernels_release_every_array_they_make(set_a_corrected: MillModel) -> None:
    """The leaf kernels (no reference counting) neither leak nor free early the arrays their callers made.

    A leaf kernel that kept a counted view (a call of a kernel returning one) would leave the batch's work
    buffer unreleased (12 made, 8 released when _event was made to take one); one that released a view it
    never counted would free the buffer under the batch.
    """
    from numba.core.runtime import _nrt_python  # type: ignore[attr-defined]

    from millctl.physics.methods import EventCall

    scenes = random_scenes(set_a_corrected, 30, 11)
    rows = kernels.scene_rows(scenes)
    scene_call, event_call = kernels.SceneCall(), EventCall(set_a_corrected)
    kernels.first_impacts(rows[:2])  # compiled before counting
    scene_call.first_impact(scenes[0])
    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        made_before, freed_before = _counts(_nrt_python)
        for rods in ("all", "one"):
            result = kernels.first_impacts(rows, rods=rods)
            assert result.shape == (30, len(kernels.OUT))
            del result
        for scene in scenes:
            scene_call.first_impact(scene)
            event_call(scene.omega_r_rad_s, scene.omega_v_rad_s, scene.theta0_rad, scene.alpha0_rad)
        made_after, freed_after = _counts(_nrt_python)
        made, freed = made_after - made_before, freed_after - freed_before
    finally:
        if not was_on:
            _nrt_python.memsys_disable_stats()
    assert made > 0
    assert made == freed, f"{made} arrays (and wrappers of numpy's arrays) made by the kernels, {freed} released"


def test_event_call_is_the_batch_row_for_one_rod_and_whole_scenes(set_a_corrected: MillModel) -> None:
    """A prepared call of one model gives the batch kernel's row, bit for bit, for either question."""
    from millctl.physics.methods import EventCall
    from millctl.physics.model import Scene

    scenes = [
        Scene(set_a_corrected, s.omega_r_rad_s, s.omega_v_rad_s, s.theta0_rad, s.alpha0_rad)
        for s in random_scenes(set_a_corrected, 40, 12)
    ]
    rows = kernels.scene_rows(scenes)
    for rods, horizon, cap in (("one", math.inf, 2.0), ("all", 5.0, math.inf)):
        call = EventCall(set_a_corrected, rods=rods)
        want = kernels.first_impacts(rows, rods=rods, horizon_s=horizon, flight_cap_s=cap)
        found = 0
        for scene, row in zip(scenes, want, strict=True):
            got = call(scene.omega_r_rad_s, scene.omega_v_rad_s, scene.theta0_rad, scene.alpha0_rad)
            expected = None if row[kernels.OUT.index("found")] != 1.0 else row.tolist()
            assert _same(None if got is None else got.tolist(), expected), (rods, scene)
            found += got is not None
        assert found > 0


def test_event_call_checks_its_settings_once(set_a_corrected: MillModel) -> None:
    from millctl.errors import PhysicsInputError
    from millctl.physics.methods import EventCall

    with pytest.raises(PhysicsInputError, match="rods = 'some'"):
        EventCall(set_a_corrected, rods="some")
    with pytest.raises(PhysicsInputError, match="tol_s = -1"):
        EventCall(set_a_corrected, tol_s=-1.0)
    assert EventCall(set_a_corrected)(0.0, 0.0) is None  # nothing moves: the rods stay pinned

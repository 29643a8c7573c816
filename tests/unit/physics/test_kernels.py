"""The compiled kernels against the numpy/scipy reference engine (issue 17).

The agreement is counted on a seeded sample here; ``python -m bench`` counts it on 10⁴ scenes.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from millctl.errors import PhysicsInputError
from millctl.physics import kernels
from millctl.physics.agreement import compare, random_scenes
from millctl.physics.batch import BATCH_DTYPE, SceneBatch, first_impacts
from millctl.physics.methods import first_impact
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import simulate

AGREEMENT_SEED = 17


def test_batch_agrees_with_reference_engine_on_random_scenes(set_a_corrected: MillModel) -> None:
    report = compare(random_scenes(set_a_corrected, 300, AGREEMENT_SEED))
    print(f"agree {report.agree}/{report.scenes}, largest |Δt| {report.largest_time_difference_s:.3g} s")
    assert report.disagreements == []
    assert report.largest_time_difference_s < 1e-12


def test_batch_agrees_in_the_paper_variant(set_a_paper: MillModel) -> None:
    report = compare(random_scenes(set_a_paper, 60, AGREEMENT_SEED + 1))
    assert report.disagreements == []


def test_single_event_is_the_batch_row(set_a_corrected: MillModel) -> None:
    scenes = random_scenes(set_a_corrected, 5, 3)
    rows = first_impacts(SceneBatch.from_scenes(scenes), rods="all")
    for scene, row in zip(scenes, rows, strict=True):
        event = first_impact(scene, "exact")
        assert event is not None and bool(row["found"])
        assert (event.time_s, event.rod, event.partner, event.energy_j) == (
            row["time_s"],
            row["rod"],
            row["partner"],
            row["energy_j"],
        )
        reference = first_impact(scene, "exact-reference")
        assert reference is not None
        assert reference.energy_j == pytest.approx(event.energy_j, rel=1e-9)


def test_zero_length_flight_books_no_impact(set_a_corrected: MillModel) -> None:
    """A free path that enters the wall at once is no flight (scene 166 of the 10³ sample: N falls with
    N' < 0 but the rod, released from the wall's drag, would slide outwards). The old engine booked an
    impact 4e-17 s after the departure; now every engine holds the rod through the dip."""
    scene = random_scenes(set_a_corrected, 1000, AGREEMENT_SEED)[166]
    impacts = simulate(scene, 5.0, stop_after_first=True).impacts
    row = first_impacts(SceneBatch.from_scenes([scene]), rods="all")[0]
    assert float(impacts[0]["flight_time_s"]) > 1e-6
    assert row["zero_length_flights"] >= 1
    assert float(row["time_s"]) == pytest.approx(float(impacts[0]["time_s"]), abs=1e-12)


def test_repinned_rod_stays_in_the_contact_search(set_a_corrected: MillModel) -> None:
    """Scene 289: rod 0 is put back on the wall (zero-length flight) beside rod 5, which flies into it at
    0.0966 s. The old engine excluded the pair (side by side on the wall counted as 'still touching') and
    found that contact or not depending on the horizon."""
    scene = random_scenes(set_a_corrected, 1000, AGREEMENT_SEED)[289]
    for t_end in (0.2, 5.0):
        first = simulate(scene, t_end, stop_after_first=True).impacts[0]
        assert (int(first["rod"]), int(first["partner"])) == (5, 0)
        assert float(first["time_s"]) == pytest.approx(0.09662709967, abs=1e-10)


def test_one_rod_events_hold_the_other_rods(set_a_corrected: MillModel) -> None:
    batch = SceneBatch.broadcast(
        set_a_corrected,
        omega_r_rad_s=np.linspace(5.0, 20.0, 4)[:, None],
        omega_v_rad_s=np.array([0.0, 80.0])[None, :],
    )
    result = first_impacts(batch, rods="one")
    assert result.dtype == BATCH_DTYPE and len(result) == 8
    found = result[result["found"]]
    assert len(found) > 0
    assert np.all(found["rod"] == 0) and np.all(found["backed"])
    assert np.all(found["flight_time_s"] > 0.0)


def test_batch_rejects_bad_input(set_a_corrected: MillModel) -> None:
    with pytest.raises(PhysicsInputError, match=r"omega_r_rad_s\[1\] = -1.0"):
        SceneBatch.broadcast(set_a_corrected, omega_r_rad_s=[1.0, -1.0], omega_v_rad_s=0.0)
    with pytest.raises(PhysicsInputError, match="theta0_rad"):
        SceneBatch.broadcast(set_a_corrected, omega_r_rad_s=1.0, omega_v_rad_s=0.0, theta0_rad=math.nan)
    with pytest.raises(PhysicsInputError, match="rods"):
        first_impacts(SceneBatch.broadcast(set_a_corrected, omega_r_rad_s=1.0, omega_v_rad_s=0.0), rods="two")
    with pytest.raises(ValueError, match="shape"):
        kernels.first_impacts(np.zeros((2, 3)))


def test_pinned_scene_has_no_impact(set_a_corrected: MillModel) -> None:
    fast = Scene(dataclasses.replace(set_a_corrected, eccentricity_m=0.0), 40.0, 0.0)  # r0 ω² > g: never leaves
    row = first_impacts(SceneBatch.from_scenes([fast]), rods="all")[0]
    assert not row["found"] and math.isnan(row["first_detach_time_s"])


def test_flight_after_a_long_run_keeps_its_digits(set_a_corrected: MillModel) -> None:
    """A flight is evaluated in its own time τ and the departure's cam phase (issue 17, phase not absolute time).

    The old kernel rebuilt the cam phase as α0 + ω_v t0 and took sin(α0 + ω_v t0 + ω_v τ) − sin α_d: after a
    departure at t0 = 2¹⁷ s (ω_v t0 ≈ 1.6e7 rad, one ulp ≈ 4e-9 rad) its lift lost ~1e-12 m. The same flight
    from t0 = 0 and from t0 = 2¹⁷ s must now land on the same point to the last digits.
    """
    row = kernels.scene_row(Scene(set_a_corrected, 12.0, 120.0))
    w_v, alpha_d, tau = 120.0, 0.3, 2.0**-10  # t0 + τ exact in binary: τ is recovered without rounding
    positions = []
    for t0 in (0.0, 2.0**17):
        p = row.copy()
        p[kernels.PARAMS.index("omega_v_rad_s")] = w_v
        p[kernels.PARAMS.index("alpha0_rad")] = alpha_d - w_v * t0  # the cam is at α_d when the rod departs
        state = np.zeros((1, 10))
        # flying, departed at t0 from the top of the wall with a sideways speed; sin, cos of α_d
        state[0, :] = [1.0, t0, 0.0, 0.0, 0.018, -0.2, 0.0, 0.0, math.sin(alpha_d), math.cos(alpha_d)]
        positions.append(np.array(kernels._rel(p, state, 0, t0 + tau)))
    assert np.max(np.abs(positions[1] - positions[0])) <= 1e-16


def test_a_loose_tolerance_still_names_the_first_pair(set_a_corrected: MillModel) -> None:
    """At the packing limit (neighbours 1e-9 apart) rods 2–1 and 4–5 touch 3e-11 s apart. With tol = 1e-7 or
    1e-9 s the old kernel ordered the two by their loose roots and named 4–5 (the benchmark counted a missed
    event); candidates closer than the tolerance are now ordered at full precision."""
    packed = dataclasses.replace(
        set_a_corrected, rod_radius_m=set_a_corrected.vial_radius_m / 3.0 * (1.0 - 1e-9), n_rods=6
    )
    scene = Scene(packed, 10.0, 60.0, -0.5 * math.pi, 0.2)
    exact = first_impact(scene, "exact")
    assert exact is not None and (exact.rod, exact.partner) == (2, 1)
    for tol in (1e-7, 1e-9):
        event = first_impact(scene, "exact", tol=tol)
        assert event is not None and (event.rod, event.partner) == (2, 1)
        assert abs(event.time_s - exact.time_s) <= 2.0 * tol


def test_records_carry_every_kernel_column_with_its_type() -> None:
    # the compiled record fill against numpy's per-field expression of the same rules, nan rows included
    from millctl.physics.batch import as_records

    rng = np.random.default_rng(5)
    raw = rng.normal(size=(257, len(kernels.OUT)))
    raw[:, kernels.OUT.index("found")] = rng.integers(0, 2, 257)
    raw[:, kernels.OUT.index("backed")] = rng.integers(0, 2, 257)
    for name in ("rod", "partner", "zero_length_flights"):
        raw[:, kernels.OUT.index(name)] = rng.integers(-1, 6, 257)
    raw[::3] = np.nan
    rec = as_records(raw)
    col = {name: raw[:, k] for k, name in enumerate(kernels.OUT)}
    for name in BATCH_DTYPE.names or ():
        if name == "flight_time_s":
            expected = col["time_s"] - col["depart_time_s"]
        elif BATCH_DTYPE[name].kind == "i":
            expected = np.where(np.isfinite(col[name]), col[name], -1).astype(np.int32)
        elif BATCH_DTYPE[name].kind == "b":
            expected = col[name] == 1.0
        else:
            expected = col[name]
        assert np.array_equal(rec[name], expected, equal_nan=True), name
    with pytest.raises(ValueError, match=r"kernels\.OUT"):
        as_records(raw[:, :5])

"""Item 4 of issue 20: the flight time is the root itself, in the flight's own clock (no cancellation).

With r_d = 0 and the corrected law (N = 0 exactly at departure) the wall gap of a
departing rod is τ³·(g² τ/4 − g u_y) for a departure at the bottom half's exit
angle, so the engine's flight from its own departure state (x_0, y_0, u_x, u_y)
is τ_f = 4 u_y / g in closed form. At ω_r = 5 rpm the departure is near t = 3 s,
where one ulp of time is 4.4e-16 s, i.e. 1.2e-13 of the 3.8 ms flight: the old
difference t_contact − t_d could not get closer than that; the root in τ can.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from millctl.physics.detachment import find_detachment
from millctl.physics.events import WALL, earliest_contact
from millctl.physics.flight import RodState, WallState, depart
from millctl.physics.model import MillModel, Scene
from millctl.physics.simulate import simulate
from millctl.physics.telemetry import revolution_summary
from millctl.units import rpm_to_rad_s

FIVE_RPM = rpm_to_rad_s(5.0)


@pytest.fixture(scope="module")
def still_cam(set_a_corrected: MillModel) -> MillModel:
    return dataclasses.replace(set_a_corrected, eccentricity_m=0.0, n_rods=1)


@pytest.mark.parametrize("theta0", [-0.5 * math.pi, -2.0, -1.2, -0.4])
def test_flight_time_is_carried_not_differenced(still_cam: MillModel, theta0: float) -> None:
    scene = Scene(still_cam, FIVE_RPM, 50.0, theta0, 0.7)
    det = find_detachment(scene)
    assert det.detached and det.time_s > 0.1
    flight = depart(scene, WallState(0.0, theta0), det.time_s)
    states: list[RodState] = [flight]
    contact = earliest_contact(scene, states, det.time_s, det.time_s + 2.0)
    assert contact is not None and contact.partner == WALL
    expected = 4.0 * flight.uy0_m_s / still_cam.g_m_s2  # closed form for this very departure state
    assert abs(contact.flight_time_s - expected) <= 4 * math.ulp(expected)
    assert contact.time_s == pytest.approx(det.time_s + contact.flight_time_s, abs=2 * math.ulp(contact.time_s))


def test_flight_time_near_three_seconds_in_simulate_and_telemetry(still_cam: MillModel) -> None:
    """The offline records and the node telemetry carry τ_f; against the exact departure (sin θ_d = r0 ω_r²/g).

    What remains in the offline record is the detachment time's own rounding (brentq to a
    few ulp of t_d ≈ 3 s), amplified by 1/τ_f: ≈ 5e-14 here, the conditioning limit.
    """
    sin_d = still_cam.r0_m * FIVE_RPM**2 / still_cam.g_m_s2
    exact = 4.0 * still_cam.r0_m * FIVE_RPM * math.sqrt(1.0 - sin_d * sin_d) / still_cam.g_m_s2
    scene = Scene(still_cam, FIVE_RPM, 50.0, -0.5 * math.pi, 0.7)
    run = simulate(scene, 5.0, stop_after_first=True)
    assert len(run.impacts) == 1 and run.detachments[0]["time_s"] > 2.9
    assert float(run.impacts[0]["flight_time_s"]) == pytest.approx(exact, rel=1e-13)
    summary = revolution_summary(still_cam, FIVE_RPM, 50.0, cam_phases=1)
    assert summary.mean_flight_time_s == pytest.approx(exact, rel=1e-14)

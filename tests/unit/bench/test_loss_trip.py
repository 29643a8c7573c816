"""bench/loss_trip.py on tiny inputs: the structure and the extremes, never a timing."""

from __future__ import annotations

import pytest

from bench import loss_trip


def test_no_loss_never_trips_and_heavy_loss_nearly_always_does() -> None:
    assert loss_trip.trip_probability(0.0, frames=60, trials=20) == 0.0
    assert loss_trip.trip_probability(0.7, frames=200, trials=50) > 0.9


def test_the_default_seed_replays_a_dense_stretch_of_loss() -> None:
    """The stretch docs/operations.md ("Fault seeds") names: 32 of draws 200-299 under 0.2, for node seed 0."""
    assert loss_trip.stretch_loss(0, 0.2, 200, 300) == pytest.approx(0.32)
    assert loss_trip.stretch_loss(0, 0.2, 100, 200) < 0.2


def test_main_prints_the_probability_and_the_stretches(capsys: pytest.CaptureFixture[str]) -> None:
    assert loss_trip.main(["--trials", "20", "--frames", "30"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("independent loss 0.2 over 30 frames: ")
    stretches = [line.split(":")[1].strip() for line in lines[1:]]
    assert stretches == ["draws 0-99", "draws 100-199", "draws 200-299", "draws 300-399"]


def test_main_names_a_bad_argument(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        loss_trip.main(["--loss", "1.5"])
    assert "--loss" in capsys.readouterr().err

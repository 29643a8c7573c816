"""Level (b)'s slip onset by certified safe steps: the windowed search's first zero, to rounding."""

from __future__ import annotations

import math

import numpy as np
import pytest

from millctl.config import MillConfig
from millctl.physics import kernels
from millctl.physics.kernels.detach import _falling_zero_windowed
from millctl.physics.kernels.layout import _STATE_COLUMNS, _TRIG_COLUMNS
from millctl.physics.kernels.telemetry import _slip_onset, _slip_rows
from millctl.physics.kernels.trig import _trig
from millctl.physics.model import MillModel, Scene


def _windowed_onset(row: np.ndarray, mu: float, t_end: float) -> float:
    """The onset as the kernel found it before the safe steps: each margin by the windowed search."""
    tr = _slip_rows(row, -0.5 * math.pi, mu, np.zeros((2, _TRIG_COLUMNS)))
    st = np.zeros((1, _STATE_COLUMNS))
    onsets = []
    for r in range(2):
        value = _trig(tr, r, 0.0, 0, 1.0)
        onsets.append(0.0 if value <= 0.0 else _falling_zero_windowed(row, st, tr, r, 1.0, 0.0, t_end))
    return min(onsets)


@pytest.mark.parametrize("variant", ["corrected", "paper"])
@pytest.mark.parametrize("mu", [0.3, 1.0, 3.0])
def test_safe_steps_find_the_windowed_searchs_first_zero(config: MillConfig, variant: str, mu: float) -> None:
    rng = np.random.default_rng(40)
    physics = config.model.model_copy(update={"variant": variant})
    model = MillModel.from_config(config.model_copy(update={"model": physics}))
    rpm = 2.0 * math.pi / 60.0
    never = 0
    for _ in range(300):
        w_r, w_v = rng.uniform(5.0, 400.0) * rpm, rng.uniform(50.0, 1500.0) * rpm
        row = kernels.scene_row(Scene(model, w_r, w_v, -0.5 * math.pi, rng.uniform(0.0, 2.0 * math.pi)))
        t_end = 2.0 * math.pi / w_r * rng.uniform(0.05, 1.0)
        work = np.zeros((2, _TRIG_COLUMNS)), np.zeros((1, _STATE_COLUMNS))
        stepped = _slip_onset(row, -0.5 * math.pi, mu, t_end, *work)
        windowed = _windowed_onset(row, mu, t_end)
        if math.isinf(windowed):
            never += 1
            assert math.isinf(stepped), (w_r, w_v)
        else:
            assert stepped == pytest.approx(windowed, rel=1e-11, abs=1e-13), (w_r, w_v)
    assert 0 < never < 300  # both paths taken: rides that slip, and rides certified never to (16–128 of 300)

"""Small studies on Set A, fast enough for the unit tier."""

from __future__ import annotations

from pathlib import Path

import pytest

GRID = """
[study]
name = "grid on Set A"
seed = 7
variant = "corrected"

[parameters.rotary_rpm]
grid = { start = 80, stop = 280, num = 3 }

[parameters.vibration_rpm]
values = [400.0, 800.0]

[metrics]
names = ["milling_power_w", "dose_rate_j_g_s", "impact_energy_p90_j", "margin_corrected_best_phase_rpm"]
revolutions = 1.0
cam_phases = 2

[constraints]
law = "corrected-best-phase"
max_vibration_rpm = 1000.0

[objective]
maximize = "dose_rate_j_g_s"
"""

OPTIMISER = """
[study]
name = "optimiser on Set A"
seed = 11
variant = "corrected"
vibration_rpm = 800.0

[parameters.rotary_rpm]
bounds = [60.0, 300.0]

[metrics]
names = ["milling_power_w"]
cam_phases = 2

[constraints]
law = "corrected-best-phase"

[objective]
maximize = "milling_power_w"

[optimiser]
max_iterations = 3
population = 4
"""


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture
def grid_file(tmp_path: Path) -> Path:
    return write(tmp_path, "grid.toml", GRID)


@pytest.fixture
def optimiser_file(tmp_path: Path) -> Path:
    return write(tmp_path, "opt.toml", OPTIMISER)

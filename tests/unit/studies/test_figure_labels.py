"""Study figures stand alone: labels in words with units, the heat map's legend off the data, the Pareto axes
as plotted, infeasible points marked (issue 39, items 8 and 9)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from millctl.cli import main
from millctl.studies.figures import metric_label
from tests.conftest import CONFIG_FILE


def test_metric_identifiers_become_labels_with_units() -> None:
    assert metric_label("milling_power_w") == "milling power (W)"
    assert metric_label("-impact_energy_p90_j") == "impact energy, 90th percentile (J)"
    assert metric_label("dose_rate_j_g_s") == "dose rate (J g⁻¹ s⁻¹)"
    assert metric_label("vibration_rpm") == "ω_v, cam speed (rpm)"


def test_the_figures_read_without_the_code(grid_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    saved: dict[str, Any] = {}
    original = Figure.savefig

    def keep(self: Figure, path: Any, *args: Any, **kwargs: Any) -> None:
        saved[Path(str(path)).name] = self
        original(self, path, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    code = main(["--config", str(CONFIG_FILE), "study", str(grid_file), "--out", str(tmp_path / "r.csv"),
                 "--workers", "1", "--figures", str(tmp_path / "fig"),
                 "--pareto", "milling_power_w,-impact_energy_p90_j"])
    assert code == 0, capsys.readouterr().err
    texts = []
    for fig in saved.values():
        for ax in fig.axes:
            texts += [ax.get_xlabel(), ax.get_ylabel(), ax.get_title()]
    assert texts and not [t for t in texts if "_" in t.replace("ω_r", "").replace("ω_v", "")], texts
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    heat = saved["heatmap.png"].axes[0]
    renderer = FigureCanvasAgg(saved["heatmap.png"]).get_renderer()  # type: ignore[no-untyped-call]
    legend = heat.get_legend().get_window_extent(renderer)
    assert legend.y1 <= heat.get_window_extent(renderer).y0  # below the map, hiding no cell
    pareto = saved["pareto.png"].axes[0]
    assert pareto.get_xlabel() == "milling power (W), lower is better"
    assert pareto.get_ylabel() == "impact energy, 90th percentile (J), higher is better"
    sensitivity = saved["sensitivity.png"]
    labels = {t.get_text() for ax in sensitivity.axes if ax.get_legend() for t in ax.get_legend().get_texts()}
    assert "feasible" in labels

"""Study tables and figures stand alone: quantities by name with their units from one table, headers never cut,
the heat map's legend off the data, the Pareto axes as plotted, infeasible points marked (issue 39, items 8, 9)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

from millctl.cli import main
from millctl.studies.metrics import METRICS
from millctl.studies.schema import CATEGORICAL, Parameter
from tests.conftest import CONFIG_FILE

GREEK = ("ω_r", "ω_v")


def words(text: str) -> str:
    """``text`` without the two speed symbols, whose underscore is the paper's subscript."""
    for symbol in GREEK:
        text = text.replace(symbol, "")
    return text


def test_every_metric_and_parameter_has_one_name_and_unit() -> None:
    from millctl.studies.metrics import quantity_label
    from millctl.studies.schema import PARAMETER_NAMES

    assert quantity_label("milling_power_w") == "milling power, whole mill (W)"
    assert quantity_label("-impact_energy_p90_j") == "impact energy, 90th percentile (J)"
    assert quantity_label("dose_rate_j_g_s") == "dose rate, whole mill (J/(g·s))"
    assert quantity_label("vibration_rpm") == "ω_v, cam speed (rpm)"
    labels = [quantity_label(name) for name in METRICS]
    assert len(set(labels)) == len(labels)  # no two metrics read alike
    for name, metric in METRICS.items():
        assert "_" not in words(metric.label) and metric.unit and " " not in metric.unit, name
    for parameter in Parameter:
        label, unit = PARAMETER_NAMES[parameter]
        assert "_" not in words(label)
        assert unit or parameter in CATEGORICAL or parameter is Parameter.N_RODS, parameter
    with pytest.raises(Exception, match="'milling_power' is neither a metric nor a study parameter"):
        quantity_label("milling_power")


def test_per_rod_and_whole_mill_quantities_are_named_apart() -> None:
    from millctl.studies.metrics import quantity_label

    for name, metric in METRICS.items():
        if "per_rod" in name:
            assert metric.label.endswith("per rod"), name
    whole = ["impact_rate_hz", "paper_estimate_power_w", "milling_power_w", "dose_rate_j_g_s", "sim_impact_rate_hz",
             "slip_milling_power_w"]
    assert all("whole mill" in METRICS[n].label for n in whole)
    assert quantity_label("impact_rate_hz") != quantity_label("impact_rate_per_rod_hz").replace("per rod", "")


def test_a_table_too_wide_for_the_terminal_wraps_its_headers_between_words_and_splits() -> None:
    from millctl.cli.tables import Column, print_table
    from millctl.studies.metrics import quantity_label

    console = Console(width=60, record=True, file=open("/dev/null", "w"), color_system=None)  # noqa: SIM115
    headers = [quantity_label(n) for n in ("rotary_rpm", "vibration_rpm", "margin_corrected_best_phase_rpm",
                                           "milling_power_w", "dose_rate_j_g_s", "impact_energy_p90_j")]
    columns = [Column("point", ("3", "12"))] + [Column(h, ("0.003924", "112")) for h in headers]
    print_table(console, "grid", columns)
    text = console.export_text()
    assert "…" not in text and max(len(line) for line in text.splitlines()) <= 60
    for header in headers:
        for word in header.split():
            assert word in text, word  # every word whole, none cut
    assert "grid (part 1 of 2)" in text and "grid (part 2 of 2)" in text
    assert text.count("point") == 2  # each part repeats the point's number


@pytest.mark.parametrize("width", [80, 160])
def test_the_study_table_names_its_columns_in_words_and_cuts_none(
    grid_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], width: int
) -> None:
    monkeypatch.setattr("millctl.cli.output.PIPE_WIDTH", width)
    labels = {
        "milling_power_w": "milling power, whole mill (W)",
        "dose_rate_j_g_s": "dose rate, whole mill (J/(g·s))",
        "impact_energy_p90_j": "impact energy, 90th percentile (J)",
        "margin_corrected_best_phase_rpm": "margin to the corrected-best-phase limit (rpm)",
        "rotary_rpm": "ω_r, vial speed (rpm)",
    }
    code = main(["--config", str(CONFIG_FILE), "study", str(grid_file), "--out", str(tmp_path / "r.csv"),
                 "--workers", "1", "--pareto", "milling_power_w,-impact_energy_p90_j"])
    out = capsys.readouterr().out
    assert code == 0
    assert "…" not in out and max(len(line) for line in out.splitlines()) <= width
    for name, label in labels.items():
        assert name not in out
        for word in label.split():
            assert word in out, word
    assert "objective:" in out
    assert "milling power, whole mill (W), higher is better and impact energy, 90th percentile (J), lower is better" \
        in " ".join(out.split())


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
    assert texts and not [t for t in texts if "_" in words(t)], texts
    from tests.unit.figure_checks import legends_beside_the_data

    for fig in saved.values():
        legends_beside_the_data(fig)  # the heat map's too: below the map, hiding no cell
    pareto = saved["pareto.png"].axes[0]
    # --pareto maximises milling_power_w and minimises -impact_energy_p90_j; the raw values are plotted
    assert pareto.get_xlabel() == "milling power, whole mill (W), higher is better"
    assert " ".join(pareto.get_ylabel().split()) == "impact energy, 90th percentile (J), lower is better"
    sensitivity = saved["sensitivity.png"]
    labels = {t.get_text() for legend in sensitivity.legends for t in legend.get_texts()}
    assert {"feasible", "infeasible (a constraint is violated)"} <= labels
    crosses = [line for ax in sensitivity.axes for line in ax.get_lines() if line.get_marker() == "x"]
    assert crosses and all(len(line.get_xdata()) for line in crosses)  # 280 rpm breaks the envelope


def test_every_study_figure_is_legible_at_one_column(grid_file: Path, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    from tests.unit.figure_checks import legible_at_one_column

    saved: dict[str, Figure] = {}
    original = Figure.savefig

    def keep(self: Figure, path: Any, *args: Any, **kwargs: Any) -> None:
        saved[Path(str(path)).name] = self
        original(self, path, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    assert main(["--config", str(CONFIG_FILE), "study", str(grid_file), "--out", str(tmp_path / "r.csv"),
                 "--workers", "1", "--figures", str(tmp_path / "fig"),
                 "--pareto", "milling_power_w,-impact_energy_p90_j"]) == 0
    assert set(saved) == {"heatmap.png", "pareto.png", "sensitivity.png"}
    for name, fig in saved.items():
        legible_at_one_column(fig, name)

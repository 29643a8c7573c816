"""`millctl study`: table, --json, resume, figures, --pareto, --recipe; and the shipped example studies."""

from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

import pytest

from millctl.cli import main
from millctl.config import MillConfig
from millctl.studies import SerialBackend, Study, StudyRunner, load_study
from tests.conftest import CONFIG_FILE, REPO

STUDIES = REPO / "config" / "studies"


class Printed(NamedTuple):
    """What a command printed."""

    out: str
    err: str


def study(capsys: pytest.CaptureFixture[str], *args: str | Path) -> tuple[int, Printed]:
    """``millctl study ARGS``: its exit code and what it printed."""
    code = main(["--config", str(CONFIG_FILE), "study", *map(str, args)])
    captured = capsys.readouterr()
    return code, Printed(captured.out, captured.err)


def test_json_then_resume_then_figures_pareto_and_recipe(
    grid_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "r.csv"
    code, res = study(capsys, grid_file, "--out", out, "--workers", "1", "--json")
    assert code == 0, res.err
    first = json.loads(res.out)["result"]
    assert first["points"] == 6 and first["computed"] == 6 and first["reused"] == 0
    assert first["best"]["feasible"] and out.read_text().startswith("# millctl study fingerprint=")
    recipe = tmp_path / "best.toml"
    figures = tmp_path / "fig"
    code, res = study(
        capsys, grid_file, "--out", out, "--workers", "1", "--json", "--figures", figures,
        "--pareto", "milling_power_w,-impact_energy_p90_j", "--recipe", recipe, "--dose-kj-g", "0.5",
    )  # fmt: skip
    assert code == 0, res.err
    again = json.loads(res.out)["result"]
    assert again["computed"] == 0 and again["reused"] == 6 and again["best"] == first["best"]
    assert {p.rsplit("/", 1)[-1] for p in again["figures"]} == {"heatmap.png", "sensitivity.png", "pareto.png"}
    assert again["pareto_front"] and all(r["feasible"] for r in again["pareto_front"])
    assert again["recipe"]["point"] == first["best"]["point"]
    # the recipe passes the same pre-flight as any other, and mills to the dose at the best point
    assert main(["--config", str(CONFIG_FILE), "recipe", "check", str(recipe)]) == 0
    text = recipe.read_text()
    assert "dose_kj_g = 0.5" in text and f"rotary_rpm = {first['best']['rotary_rpm']!r}" in text


def test_table_on_stdout_summary_on_stderr(grid_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, res = study(capsys, grid_file, "--out", tmp_path / "r.parquet", "--workers", "1", "--top", "2")
    assert code == 0
    assert "best 2 of" in res.out and "dose_rate_j_g_s" in res.out
    assert "6 points (6 computed, 0 from" in res.err


def test_bad_arguments_exit_1(grid_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, res = study(capsys, grid_file, "--out", tmp_path / "r.csv", "--pareto", "milling_power_w")
    assert code == 1 and "--pareto" in res.err
    code, res = study(capsys, tmp_path / "missing.toml")
    assert code == 1 and "no such file" in res.err


@pytest.mark.parametrize(
    ("name", "best"),
    [("paper-operating-point.toml", (188.0, 800.0)), ("corrected-operating-point.toml", None)],
)
def test_shipped_studies_near_the_papers_point(name: str, best: tuple[float, float] | None, config: MillConfig) -> None:
    """The shipped studies on a few points around the paper's 200/800 rpm (the full grids run from the CLI)."""
    data = load_study(STUDIES / name).model_dump(mode="json")
    data["parameters"] = {"rotary_rpm": {"values": [184.0, 188.0, 192.0]}, "vibration_rpm": {"values": [750.0, 800.0]}}
    small = Study.model_validate(data)
    result = StudyRunner(small, config, name).run(SerialBackend())
    if best is not None:
        assert result.best is not None, "no feasible point among the shipped study's"
        # the paper's reasoning reproduces its conclusion: 200/800 less the interlock's 5 % margin
        assert (result.best["rotary_rpm"], result.best["vibration_rpm"]) == best
        # ... where the paper's own model, run in time, and the corrected laws disagree
        assert result.best["margin_paper_every_cycle_rpm"] < 0.0
        assert result.best["margin_corrected_every_phase_rpm"] < 0.0
    else:
        # the corrected every-phase envelope excludes the whole neighbourhood of the paper's point
        assert result.best is None
        assert len(result.rows) == 6  # the 3 × 2 grid above, each point judged
        assert all("corrected-every-phase" in r["violations"] for r in result.rows)

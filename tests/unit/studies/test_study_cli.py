"""`millctl study`: table, --json, resume, figures, --pareto, --recipe; and the shipped example studies."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import NamedTuple

import pytest

from millctl.cli import main
from millctl.config import MillConfig
from millctl.physics import structure as st
from millctl.studies import SerialBackend, Study, StudyRunner, load_study
from millctl.studies.metrics import METRICS
from millctl.studies.run import HEAP_SHARE, heap_caveat
from millctl.studies.schema import Parameter
from millctl.units import rad_s_to_rpm
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
    assert "best 2 of" in res.out and "(J/(g·s))" in res.out and "dose_rate_j_g_s" not in res.out  # names, not ids
    assert "6 points (6 computed, 0 from" in res.err


def test_bad_arguments_exit_1(grid_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, res = study(capsys, grid_file, "--out", tmp_path / "r.csv", "--pareto", "milling_power_w")
    assert code == 1 and "--pareto" in res.err
    code, res = study(capsys, tmp_path / "missing.toml")
    assert code == 1 and "no such file" in res.err


def _small(name: str, rotary: list[float], vibration: list[float], *, slip_ride: bool = True,
           **constraints: object) -> Study:
    """A shipped study on a few of its points (the full grid runs from the CLI), slip on 2 phases.

    ``slip_ride=False`` leaves out the slip ride's metrics (level s, ~0.1 s a point) and the comparison on them.
    """
    data = load_study(STUDIES / name).model_dump(mode="json")
    data["parameters"] |= {"rotary_rpm": {"values": rotary}, "vibration_rpm": {"values": vibration}}
    data["metrics"]["slip_phases"] = 2
    if not slip_ride:
        data["metrics"]["names"] = [m for m in data["metrics"]["names"] if METRICS[m].level != "s"]
        data["objective"]["compare"] = []
    data["constraints"] |= constraints
    return Study.model_validate(data)


def _with(config: MillConfig, **spring: float) -> MillConfig:
    data = config.model_dump(mode="json")
    data["mill"]["spring"] |= spring
    return MillConfig.model_validate(data)


def test_the_shipped_operating_point_study_has_no_input_that_fixes_its_answer() -> None:
    study = load_study(STUDIES / "paper-operating-point.toml")
    c = study.constraints
    assert c.max_vibration_rpm is None and c.max_spring_force_n is None and str(c.law) == "none"
    assert c.cam_contact and c.contact_fatigue  # the structural constraint, in physical terms
    assert study.study.rotary_rpm is None and study.study.vibration_rpm is None
    assert study.objective.terms == {"milling_power_w": 1.0} and study.objective.compare == ["slip_milling_power_w"]
    assert study.parameters[Parameter.VARIANT].values == ["paper", "corrected"]


def test_the_structural_limit_is_the_roller_leaving_the_cam(config: MillConfig) -> None:
    """The best cam speed is the fastest below the follower jump computed from the structure, not an input."""
    jump_rpm = rad_s_to_rpm(st.follower_jump_rad_s(st.StructureParams.from_config(config)))
    below = 100.0 * math.floor(jump_rpm / 100.0)
    above = below + 100.0
    result = StudyRunner(_small("paper-operating-point.toml", [200.0], [below - 100.0, below, above]), config, "x").run(
        SerialBackend()
    )
    for row in result.rows:
        assert (row["vibration_rpm"] > jump_rpm) == ("roller leaves the cam" in row["violations"])
    paper = next(f for f in result.findings if f["variant"] == "paper" and f["criterion"] == "objective")
    assert paper["vibration_rpm"] == below


def test_old_bounds_and_k_do_not_move_the_corrected_optimum(config: MillConfig) -> None:
    """k enters only the paper's eq. 7, and a bound on ω_v above the structural limit changes nothing."""
    rotary, vibration = [40.0, 50.0, 200.0], [800.0, 900.0, 1100.0]

    def best(study: Study, cfg: MillConfig) -> tuple[float, float]:
        found = StudyRunner(study, cfg, "x").run(SerialBackend()).findings
        f = next(f for f in found if f["variant"] == "corrected" and f["criterion"] == "objective")
        return f["rotary_rpm"], f["vibration_rpm"]

    def small(**constraints: object) -> Study:
        return _small("paper-operating-point.toml", rotary, vibration, slip_ride=False, **constraints)

    plain = best(small(), config)
    assert plain == best(small(max_vibration_rpm=1100.0), config)
    assert plain == best(small(), _with(config, stiffness_n_per_m=500.0))


def test_findings_cover_both_models_with_and_without_slip(config: MillConfig) -> None:
    result = StudyRunner(_small("paper-operating-point.toml", [200.0], [800.0]), config, "x").run(SerialBackend())
    got = {(f["variant"], f["criterion"]) for f in result.findings}
    assert got == {(v, c) for v in ("paper", "corrected") for c in ("objective", "slip_milling_power_w")}
    for f in result.findings:
        row = next(r for r in result.rows if r["point"] == f["point"])
        metric = "milling_power_w" if f["criterion"] == "objective" else f["criterion"]
        assert f["value"] == row[metric]


def test_the_corrected_study_is_bounded_by_its_envelope_and_the_structure(config: MillConfig) -> None:
    data = load_study(STUDIES / "corrected-operating-point.toml").model_dump(mode="json")
    assert data["constraints"]["max_vibration_rpm"] is None
    data["parameters"] = {"rotary_rpm": {"values": [40.0, 188.0]}, "vibration_rpm": {"values": [800.0, 1100.0]}}
    result = StudyRunner(Study.model_validate(data), config, "x").run(SerialBackend())
    assert result.best is not None and (result.best["rotary_rpm"], result.best["vibration_rpm"]) == (40.0, 800.0)
    by_speed = {(r["rotary_rpm"], r["vibration_rpm"]): r["violations"] for r in result.rows}
    assert "corrected-every-phase" in by_speed[(188.0, 800.0)]
    assert "roller leaves the cam" in by_speed[(40.0, 1100.0)]


HEAPED = """
[study]
name = "slip ride at the paper's point"
seed = 7
variant = "corrected"

[parameters.rotary_rpm]
values = [200.0]

[parameters.vibration_rpm]
values = [800.0]

[metrics]
names = ["slip_sim_power_w"]
revolutions = 2.0

[objective]
maximize = "slip_sim_power_w"
compare = ["milling_power_w"]
"""


def test_a_finding_of_the_slip_ride_says_when_its_rods_heap_through_each_other(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # held rods do not meet in level (c): at 200/800 most of the slide time is spent inside another rod; the
    # share comes with any slip_sim metric, and the finding of a slip_sim criterion says so (the other not)
    path = tmp_path / "heaped.toml"
    path.write_text(HEAPED, encoding="utf-8")
    code, res = study(capsys, path, "--out", tmp_path / "r.csv", "--workers", "1", "--json")
    assert code == 0, res.err
    summary = json.loads(res.out)["result"]
    assert "slip_sim_overlap_share" in summary["metrics"]
    assert summary["best"]["slip_sim_overlap_share"] > HEAP_SHARE
    caveats = {f["criterion"]: f.get("caveat") for f in summary["findings"]}
    assert caveats["milling_power_w"] is None
    objective = caveats["objective"]
    assert "heaped through each other" in objective and "slip_sim_overlap_share > 0.5" in objective
    code, res = study(capsys, path, "--out", tmp_path / "r.csv", "--workers", "1")
    assert code == 0 and f"caveat: {objective}" in " ".join(res.out.split())


def test_the_heap_caveat_needs_a_slip_sim_criterion_and_a_share_above_its_bound() -> None:
    row = {"point": 3, "slip_sim_overlap_share": 0.85}
    assert heap_caveat(row, ["slip_sim_power_w"]) is not None
    assert heap_caveat(row, ["milling_power_w"]) is None
    assert heap_caveat(row | {"slip_sim_overlap_share": 0.05}, ["slip_sim_power_w"]) is None
    assert heap_caveat(row | {"slip_sim_overlap_share": math.nan}, ["slip_sim_power_w"]) is None
    assert heap_caveat({"point": 3}, ["slip_sim_power_w"]) is None  # a row from before the metric existed

"""``millctl limits --plot``: the figure an operator reads, checked by its artists and legend, and written."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from millctl.cli import main
from millctl.cli.limits_plot import OperatingPoints, limits_figure
from millctl.config import load_config
from millctl.config.loader import packaged_file
from millctl.errors import ExitCode
from millctl.physics.limits import LAWS
from millctl.safety import Envelope, SpeedPoint

CONFIG = str(packaged_file("mill.toml"))
ENVELOPE = Envelope.from_config(load_config(CONFIG).config)
POINTS = OperatingPoints(
    measured=SpeedPoint(181.0, 799.0),
    target=SpeedPoint(180.0, 800.0),
    recipe=(SpeedPoint(120.0, 400.0), SpeedPoint(180.0, 800.0)),
    recipe_label="recipe demo",
    at=(SpeedPoint(250.0, 1000.0),),
)


def legend_labels(fig: Figure, panel: int) -> list[str]:
    legend = fig.axes[panel].get_legend()
    assert legend is not None
    return [" ".join(text.get_text().split()) for text in legend.get_texts()]  # entries wrap to the column


def test_the_envelope_panel_names_every_law_the_regime_and_the_points() -> None:
    labels = legend_labels(limits_figure(ENVELOPE, "Set A", POINTS), 0)
    assert labels[0] == "allowed: paper-eq9 − 5% margin (the interlock enforces this)"
    for law in LAWS:
        assert sum(label.startswith(f"{law.value}: ") for label in labels) == 1, law
    assert "paper-eq9: paper eq. 9 as printed — configured law, no margin" in labels
    assert labels.count("⚠ above ω_v = 307.8 rpm paper-eq9 is not the every-cycle bound") == 1
    assert "planned: recipe demo" in labels and "planned: 1 point(s) given with --at" in labels
    assert "planned point outside the envelope (1): the interlock refuses it" in labels  # 250 rpm at 1000 rpm
    assert "measured now: ω_v 799, ω_r 181 rpm" in labels and "target now: ω_v 800, ω_r 180 rpm" in labels


def test_the_allowed_region_is_the_enforced_envelope_and_the_hatch_starts_at_the_switch() -> None:
    ax = limits_figure(ENVELOPE, "Set A").axes[0]
    polygons = [c for c in ax.collections if isinstance(c, PolyCollection)]
    (allowed,) = [c for c in polygons if str(c.get_label()).startswith("allowed")]
    top = np.asarray(allowed.get_paths()[0].vertices)[:, 1].max()
    assert top == pytest.approx(float(ENVELOPE.omega_r_limit_rpm(ENVELOPE.vibration_max_rpm)), rel=1e-9)
    (hatched,) = [p for p in ax.patches if str(p.get_label()).startswith("⚠")]
    assert hatched.get_hatch() == "//"
    assert np.asarray(hatched.get_path().vertices)[:, 0].min() == 0.0  # axvspan in axes-relative x ...
    x0 = hatched.get_transform().transform((0.0, 0.0))[0]
    assert ax.transData.inverted().transform((x0, 0.0))[0] == pytest.approx(307.8, abs=0.05)  # ... at 307.8 rpm


def test_no_points_no_point_legend() -> None:
    labels = legend_labels(limits_figure(ENVELOPE, "Set A"), 0)
    assert not [label for label in labels if label.startswith(("planned", "measured", "target"))]


def test_the_sin_alpha_panel_shades_the_admissible_phases() -> None:
    fig = limits_figure(ENVELOPE, "Set A")
    labels = legend_labels(fig, 1)
    assert "admissible: eq. 7 gives a real detachment angle" in labels
    assert "printed eq. 8b (erratum: inconsistent units, not used)" in labels
    ax = fig.axes[1]
    (shade,) = [c for c in ax.collections if str(c.get_label()).startswith("admissible")]
    ys = np.asarray(shade.get_paths()[0].vertices)[:, 1]
    assert ys.min() == pytest.approx(-1.0) and ys.max() == pytest.approx(1.0)  # only sin α ∈ [−1, 1] is shaded
    assert ax.get_ylim() == pytest.approx((-1.15, 1.15))


def test_plot_writes_the_png_and_warns_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "limits.png"
    recipe = str(Path(__file__).resolve().parents[2] / "config" / "recipes" / "demo.toml")
    code = main(["--config", CONFIG, "limits", "--plot", str(out), "--recipe", recipe, "--at", "1000", "250"])
    assert code == ExitCode.OK
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    err = capsys.readouterr().err
    assert err.count("warning:") == 1 and err.count("307.8 rpm") == 1, err


def test_plot_without_a_file_writes_limits_png_here(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["--config", CONFIG, "limits", "--plot", "--vib-rpm", "800"]) == ExitCode.OK
    assert (tmp_path / "limits.png").read_bytes()[:4] == b"\x89PNG"


def test_live_without_a_service_is_a_clear_error_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "limits.png"
    code = main(["--config", CONFIG, "limits", "--plot", str(out), "--live", "--socket", str(tmp_path / "none.sock")])
    assert code == ExitCode.BUS
    assert "none.sock" in capsys.readouterr().err and not out.exists()


def test_a_recipe_is_drawn_along_the_planners_path_not_straight_between_its_targets() -> None:
    from millctl.cli.limits_plot import planned_from_recipe

    demo = str(Path(__file__).resolve().parents[2] / "config" / "recipes" / "demo.toml")
    targets, label, route = planned_from_recipe(demo, load_config(CONFIG).config)
    fig = limits_figure(ENVELOPE, "Set A", OperatingPoints(recipe=targets, recipe_label=label, recipe_path=route))
    drawn = {line.get_label(): line for line in fig.axes[0].get_lines()}
    path = drawn["planned path: the planner's ramps, one drive after the other, and the final stop"]
    v, r = np.asarray(path.get_xdata(), dtype=float), np.asarray(path.get_ydata(), dtype=float)
    assert (v[0], r[0]) == (0.0, 0.0) and (v[-1], r[-1]) == (0.0, 0.0)  # from standstill, back by the final stop
    moves = list(zip(np.diff(v), np.diff(r), strict=True))
    assert moves and all(dv == 0.0 or dr == 0.0 for dv, dr in moves)  # one drive at a time: no diagonal
    assert len(v) > len(targets)  # corners between the targets
    markers = drawn[f"planned: {label}"]
    assert markers.get_linestyle() == "None"  # the targets are points; the line is the path


def test_the_figure_is_one_column_wide_legible_and_each_legend_right_under_its_panel() -> None:
    from tests.unit.figure_checks import legends_beside_the_data, legible_at_one_column

    fig = limits_figure(ENVELOPE, "Set A", POINTS)
    legible_at_one_column(fig, "limits")
    legends_beside_the_data(fig)
    assert [ax.get_xlabel() for ax in fig.axes] == ["vibration speed ω_v (rpm)"] * 2
    assert fig.get_suptitle().startswith("Set A: the safe speeds and cam phases")


def test_the_drawn_path_is_the_planners_sequence_corner_by_corner() -> None:
    from millctl.cli.limits_plot import planned_from_recipe
    from millctl.recipes import load_recipe, plan_recipe

    demo = str(Path(__file__).resolve().parents[2] / "config" / "recipes" / "demo.toml")
    config = load_config(CONFIG).config
    targets, label, route = planned_from_recipe(demo, config)
    fig = limits_figure(ENVELOPE, "Set A", OperatingPoints(recipe=targets, recipe_label=label, recipe_path=route))
    (path,) = [line for line in fig.axes[0].get_lines() if str(line.get_label()).startswith("planned path")]
    plan = plan_recipe(load_recipe(demo).recipe, config)
    corners = [c for step in plan.steps if step.trajectory is not None for c in step.trajectory.vertices()]
    corners += list(plan.stop.vertices())
    expected = [c for i, c in enumerate(corners) if i == 0 or c != corners[i - 1]]
    drawn = list(zip(np.asarray(path.get_xdata(), dtype=float), np.asarray(path.get_ydata(), dtype=float),
                     strict=True))
    assert drawn == [(c.omega_v_rpm, c.omega_r_rpm) for c in expected]
    assert len(drawn) > len(targets) + 1  # not the targets joined by straight lines


def test_the_cam_comparison_at_80_columns_cuts_no_header_and_no_number(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr("millctl.cli.output.PIPE_WIDTH", 80)
    assert main(["--config", CONFIG, "limits", "--cam", "double", "--vib-rpm", "400", "800"]) == 0
    out = capsys.readouterr().out
    assert "…" not in out and max(len(line) for line in out.splitlines()) <= 80
    flat = " ".join(out.split())
    for word in ("envelope,", "single", "double", "cam", "(rpm)", "corrected,", "double/single", "1.455"):
        assert word in flat, word  # every header word and every figure whole
    assert "p at the highest ω_r both envelopes allow" in flat

"""The recipe picker (each recipe with the service's pre-flight verdict) and the fault drill dialog."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from textual.pilot import Pilot
from textual.widgets import Input, OptionList, Static

from millctl.api import FaultsOut, RecipeCheckOut, SimFaultName
from millctl.config import load_config
from millctl.config.loader import packaged_file
from millctl.service.recipe import RecipeSlot
from millctl.tui import MillApp
from millctl.tui.drill import DrillRequest, FaultDrillModal
from millctl.tui.recipes import RecipePicker, recipe_files
from tests.support.tui import until
from tests.unit.tui import frozen
from tests.unit.tui.test_snapshot import SIZE, feeder

REPO = Path(__file__).resolve().parents[3]
CONFIG = load_config(packaged_file("mill.toml")).config
FOLDERS = [REPO / "config" / "recipes", REPO / "tests" / "unit" / "tui" / "recipes"]


@pytest.fixture(autouse=True)
def at_the_repo(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Paths shown relative to the repository, whatever folder pytest runs in; times in UTC."""
    monkeypatch.chdir(REPO)
    monkeypatch.setenv("TZ", "UTC")
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


async def preflight(path: str) -> RecipeCheckOut:
    """The service's own pre-flight (``POST /v1/recipe/check``'s function), in-process."""
    return RecipeSlot.check(Path(path).name, Path(path).read_text(), CONFIG)


def test_the_folders_list_each_recipe_once() -> None:
    names = [p.name for p in recipe_files([*FOLDERS, FOLDERS[0]])]
    assert names == ["demo.toml", "nisi-200-800.toml", "broken.toml", "too-fast.toml"]


def opened(app: MillApp, screen: Any, done: Callable[[], bool]) -> Callable[[Pilot[None]], Any]:
    async def run(pilot: Pilot[None]) -> None:
        await feeder(app)(pilot)
        app.push_screen(screen)
        await until(pilot, done, "the picker's checks")

    return run


def test_recipe_picker_shows_every_verdict(snap_compare: Any) -> None:
    app = MillApp(frozen.SOCKET, live=False)
    picker = RecipePicker(recipe_files(FOLDERS), preflight)
    assert snap_compare(app, terminal_size=SIZE, run_before=opened(app, picker, lambda: len(picker.checks) == 4))


async def test_only_a_recipe_that_passes_its_preflight_is_run() -> None:
    app = MillApp(frozen.SOCKET, live=False)
    chosen: list[str | None] = []
    async with app.run_test(size=SIZE) as pilot:
        picker = RecipePicker(recipe_files(FOLDERS), preflight)
        app.push_screen(picker, chosen.append)
        await until(pilot, lambda: len(picker.checks) == 4, "the preflight of the 4 recipes")
        checks = {p.name: c for p, c in picker.checks.items()}
        assert checks["demo.toml"].ok and checks["demo.toml"].steps == 4
        too_fast = checks["too-fast.toml"]
        assert not too_fast.ok and "260.0 rpm exceeds the limit 190.0" in too_fast.problems[0]
        assert not checks["broken.toml"].ok and checks["broken.toml"].recipe is None
        options = picker.query_one("#recipes", OptionList)
        options.focus()
        options.highlighted = 3  # too-fast.toml
        await pilot.press("enter")
        await pilot.pause()
        assert app.screen is picker and chosen == []
        assert "refused under paper-eq9" in str(picker.query_one("#details", Static).render())
        options.highlighted = 0  # demo.toml
        await pilot.press("enter")
        await pilot.pause()
        assert chosen == [str(REPO / "config" / "recipes" / "demo.toml")]


async def test_a_typed_recipe_file_is_added_and_checked(tmp_path: Path) -> None:
    recipe = tmp_path / "mine.toml"
    recipe.write_text((REPO / "config" / "recipes" / "demo.toml").read_text())
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=SIZE) as pilot:
        picker = RecipePicker([], preflight)
        app.push_screen(picker)
        await pilot.pause()
        assert "no recipes" in str(picker.query_one("#details", Static).render())
        picker.query_one("#path", Input).value = str(recipe)
        await pilot.press("enter")
        await until(pilot, lambda: recipe in picker.checks, f"the preflight of {recipe.name}")
        assert picker.checks[recipe].ok and picker.files == [recipe]


async def read_faults() -> FaultsOut:
    return FaultsOut(active={SimFaultName.VIB_STALL: 0.0})


def test_fault_drill_dialog(snap_compare: Any) -> None:
    app = MillApp(frozen.SOCKET, live=False)
    modal = FaultDrillModal(read_faults)
    assert snap_compare(app, terminal_size=SIZE, run_before=opened(app, modal, lambda: bool(modal.active)))


async def test_the_drill_key_exists_only_on_a_service_with_fault_injection() -> None:
    app = MillApp(frozen.SOCKET, live=False)
    async with app.run_test(size=SIZE) as pilot:
        await feeder(app)(pilot)
        app.apply_service(frozen.service_answer(fault_injection=False))
        assert app.check_action("drill", ()) is False
        assert "Fault drill" not in [c.title for c in app.get_system_commands(app.screen)]
        app.apply_service(frozen.service_answer(fault_injection=True))
        assert app.check_action("drill", ()) is True
        assert "Fault drill" in [c.title for c in app.get_system_commands(app.screen)]


async def test_the_drill_dialog_asks_for_the_fault_and_its_parameter() -> None:
    app = MillApp(frozen.SOCKET, live=False)
    chosen: list[DrillRequest | None] = []
    async with app.run_test(size=SIZE) as pilot:
        modal = FaultDrillModal(read_faults)
        app.push_screen(modal, chosen.append)
        await pilot.pause()
        modal.query_one("#faults", OptionList).highlighted = 1  # ROTARY_RUNAWAY
        await pilot.pause()
        assert "runaway speed, rpm" in str(modal.query_one("#meaning", Static).render())
        modal.query_one("#param", Input).value = "450"
        modal.query_one("#param", Input).focus()
        await pilot.press("enter")
        await pilot.pause()
        assert chosen == [DrillRequest(SimFaultName.ROTARY_RUNAWAY, True, 450.0)]
        app.push_screen(FaultDrillModal(read_faults), chosen.append)
        await pilot.pause()
        await pilot.press("x")
        await pilot.pause()
        assert chosen[-1] == DrillRequest(SimFaultName.CLEAR, False, 0.0)

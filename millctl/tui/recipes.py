"""The recipe picker (key ``n``): the recipes at hand, each with the service's pre-flight verdict, run with Enter.

Recipes are the ``*.toml`` files of ``config/recipes`` under the working
folder and of the ``recipes`` folder beside the service's configuration (when
this machine can read it). Each is sent by content to the service's
``POST /v1/recipe/check`` (its own envelope; nothing is started, no control
needed) and listed as ✓ (steps, planned time, dose) or ✗ (the first problem;
every one under the list when highlighted). Enter runs a ✓ recipe; a ✗ one
is not sent. Another file can be typed in the field at the top.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable, Iterable
from pathlib import Path
from typing import ClassVar

from rich.text import Text
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Vertical
from textual.screen import ModalScreen
from textual.widgets import Input, Label, OptionList, Static
from textual.widgets.option_list import Option

from millctl.api import RecipeCheckOut
from millctl.tui.format import duration
from millctl.tui.link import LINK_ERRORS

Preflight = Callable[[str], Awaitable[RecipeCheckOut]]
"""``check(path)`` → the service's pre-flight verdict on that recipe file."""


def recipe_files(folders: Iterable[Path]) -> list[Path]:
    """The ``*.toml`` files of the folders that exist, each once, in name order within each folder."""
    found: list[Path] = []
    for folder in folders:
        if folder.is_dir():
            found += [p.resolve() for p in sorted(folder.glob("*.toml")) if p.resolve() not in found]
    return found


def shown(path: Path) -> str:
    """A path as the operator reads it: relative to the working folder when under it."""
    try:
        return str(path.relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def verdict_line(name: str, check: RecipeCheckOut | None, error: str | None = None) -> Text:
    """One line of the list: ✓ with steps, time and dose, ✗ with the first problem, or … while checking."""
    if error is not None:
        return Text.assemble(("? ", "bold yellow"), (name, "bold"), f"  cannot check: {error}")
    if check is None:
        return Text.assemble(("… ", "bold"), (name, "bold"), "  checking…")
    if not check.ok:
        first = check.problems[0] if check.problems else "refused"
        more = f" (+{len(check.problems) - 1} more)" if len(check.problems) > 1 else ""
        return Text.assemble(("✗ ", "bold red"), (name, "bold"), f"  refused: {first}{more}")
    planned = duration(check.planned_s) + (" + waits" if check.open_ended else "")
    dose_kj_g = check.dose_kj_g
    if dose_kj_g is None:
        dose = ""
    else:
        dose = f", dose {dose_kj_g:.3g} kJ/g" if dose_kj_g >= 1.0 else f", dose {1e3 * dose_kj_g:.3g} J/g"
    return Text.assemble(("✓ ", "bold green"), (name, "bold"),
                         f"  {check.recipe}: {check.steps} steps, {planned}{dose}")


class RecipePicker(ModalScreen[str | None]):
    """Pick a recipe from a list with each one's pre-flight verdict; dismissed with the path to run (or None)."""

    BINDINGS: ClassVar[list[BindingType]] = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, files: list[Path], preflight: Preflight) -> None:
        super().__init__()
        self.files = list(files)
        self.preflight = preflight
        self.checks: dict[Path, RecipeCheckOut] = {}

    def compose(self) -> ComposeResult:
        """The list, the details of the highlighted recipe, a field for another file, the hint."""
        with Vertical(id="dialog", classes="dialog"):
            yield Label("Run a recipe — each is pre-flighted by the service against its envelope",
                        classes="dialog-title")
            yield OptionList(*(Option(verdict_line(p.name, None), id=str(p)) for p in self.files), id="recipes")
            yield Static(id="details")
            yield Input(id="path", placeholder="another recipe file: type its path and press Enter")
            yield Static("Enter runs a ✓ recipe (a ✗ one is not sent)    Esc: cancel", classes="hint")

    def on_mount(self) -> None:
        """Check every listed recipe; say so when there is none."""
        if not self.files:
            self.query_one("#details", Static).update(Text(
                "no recipes in config/recipes here or beside the service's config: type a path below"))
            self.query_one("#path", Input).focus()
        for path in self.files:
            self.check(path)

    @work(group="preflight")
    async def check(self, path: Path) -> None:
        """Ask the service's pre-flight for one file and show its verdict in the list."""
        options = self.query_one("#recipes", OptionList)
        try:
            result = await self.preflight(str(path))
        except LINK_ERRORS as exc:
            options.replace_option_prompt(str(path), verdict_line(path.name, None, str(exc)))
            return
        self.checks[path] = result
        options.replace_option_prompt(str(path), verdict_line(path.name, result))
        if options.highlighted is not None and options.get_option_at_index(options.highlighted).id == str(path):
            self.show_details(path)

    def show_details(self, path: Path) -> None:
        """Every problem of the highlighted recipe (or its plan in one line)."""
        result = self.checks.get(path)
        details = self.query_one("#details", Static)
        if result is None:
            details.update(Text(f"{shown(path)}: checking…"))
        elif result.ok:
            details.update(Text(f"{shown(path)}: inside the envelope under {result.law}; Enter runs it",
                                style="green"))
        else:
            details.update(Text("\n".join([f"{shown(path)}: refused under {result.law}", *result.problems]),
                                style="red"))

    def on_option_list_option_highlighted(self, event: OptionList.OptionHighlighted) -> None:
        """Show the highlighted recipe's details."""
        if event.option.id is not None:
            self.show_details(Path(event.option.id))

    def on_option_list_option_selected(self, event: OptionList.OptionSelected) -> None:
        """Run a ✓ recipe; a refused or unchecked one stays here with its reasons."""
        if event.option.id is None:
            return
        path = Path(event.option.id)
        result = self.checks.get(path)
        if result is not None and result.ok:
            self.dismiss(str(path))
        else:
            self.show_details(path)
            self.notify(f"{path.name} is not run: {'still being checked' if result is None else 'refused'}",
                        severity="warning", timeout=4.0)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        """Add a typed file to the list, check it and highlight it."""
        text = event.value.strip()
        if not text:
            return
        path = Path(text).expanduser().resolve()
        if not path.is_file():
            self.query_one("#details", Static).update(Text(f"{text}: no such file", style="red"))
            return
        options = self.query_one("#recipes", OptionList)
        if path not in self.files:
            self.files.append(path)
            options.add_option(Option(verdict_line(path.name, None), id=str(path)))
            self.check(path)
        options.highlighted = self.files.index(path)
        options.focus()

    def action_cancel(self) -> None:
        """Close without running."""
        self.dismiss(None)


__all__ = ["Preflight", "RecipePicker", "recipe_files", "shown", "verdict_line"]

"""The TUI's stylesheet (textual CSS), kept in Python so it ships with the package."""

from __future__ import annotations

CSS = """
Screen { layout: vertical; }
#topbar { height: 1; background: $panel; padding: 0 1; }
#offline { height: auto; display: none; background: $warning 30%; color: $text; padding: 0 1; text-style: bold; }
#offline.shown { display: block; }
#trip { height: auto; display: none; background: red; color: white; padding: 0 1; }
#trip.shown { display: block; }
.panel { border: round $primary 60%; border-title-color: $text-accent; padding: 0 1; }
#row1 { height: 20; }
#left { width: 1fr; min-width: 38; }
#envelope { width: 2fr; height: 100%; }
TrendPanel { height: 1fr; }
.panel-text { height: 3; }
.trend { height: 1fr; min-height: 1; }
#row2 { height: 8; }
#state { width: 1fr; height: 100%; }
#physics { width: 1fr; height: 100%; }
#links { width: 1.5fr; min-width: 48; height: 100%; }
#events { height: 1fr; min-height: 4; }
.dialog { width: 84; max-width: 100%; height: auto; max-height: 100%; overflow-y: auto;
          border: thick $accent; background: $surface; padding: 1 2; }
/* a dialog leaves the state bar (row 0) in sight */
SetpointsModal, RecipePicker, FaultDrillModal, ConfirmModal { align: center middle; padding-top: 1; }
#recipes, #faults { height: auto; max-height: 12; }
#details, #meaning { height: auto; margin-top: 1; }
.dialog-title { text-style: bold; margin-bottom: 1; }
.dialog > Static { width: 100%; height: auto; }
.field { height: 3; }
.field-label { width: 28; padding: 1 1 0 0; }
.field Input { width: 1fr; }
#limit, #verdict { height: auto; min-height: 1; margin-top: 1; }
.buttons { height: 3; margin-top: 1; align: right middle; }
.buttons Button { margin-left: 2; }
.hint { color: $text-muted; margin-top: 1; }
/* the set dialog on a short terminal (80 × 24): one row a field, so the verdict and the keys fit */
.dialog.-compact { padding: 0 1; }
.dialog.-compact .dialog-title { margin-bottom: 0; }
.dialog.-compact .field { height: 1; margin-bottom: 0; }
.dialog.-compact .field-label { padding: 0 1 0 0; }
.dialog.-compact .field Input { margin-right: 1; }
.dialog.-compact #limit, .dialog.-compact #verdict, .dialog.-compact .hint { margin-top: 0; }
#envelope-view { height: 1fr; }
#envelope-plot { height: 1fr; min-height: 6; }
#envelope-legend { height: auto; }

/* an 80 × 24 terminal: no trends, the panels share the height, physics gives its place to the links */
Screen.-short .trend { display: none; }
Screen.-short .panel-text { height: 1fr; }
Screen.-short #row1 { height: 1fr; min-height: 12; }
Screen.-short #row2 { height: 7; }
Screen.-short #events { height: 3; min-height: 3; }
/* short terminals: one notification at a time, at most 3 rows, over the events panel (never over the drives,
   the envelope or a dialog's fields; its whole text goes to the event log when cut: MillView.notify) */
Screen.-short ToastHolder { max-height: 3; }
Screen.-short Toast { padding: 0 1; margin-top: 0; width: 62; max-width: 78%; max-height: 3; }
Screen.-narrow #physics { display: none; }
Screen.-narrow #links { width: 1fr; min-width: 0; }
Screen.-narrow #left { min-width: 30; }
"""

SHORT_BELOW_ROWS = 34
"""Terminals with fewer rows get the compact layout (class ``-short``)."""
NARROW_BELOW_COLUMNS = 100
"""Terminals with fewer columns get the narrow layout (class ``-narrow``)."""

SHORT_TOAST_CHARS = 2 * 50
"""What a notification on a short terminal shows at most (two lines of a 60-column toast, with room for word
wrapping); longer ones are cut on screen and written whole to the event log."""

__all__ = ["CSS", "NARROW_BELOW_COLUMNS", "SHORT_BELOW_ROWS", "SHORT_TOAST_CHARS"]

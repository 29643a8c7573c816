"""The work–precision plot (docs/img/work-precision.png); needs the ``plot`` extra (matplotlib)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bench.work_precision import ERROR_FLOOR

STYLE = {
    "exact": ("o-", "exact, compiled (bracket + brentq), tol sweep"),
    "exact-reference": ("o--", "exact, numpy/scipy reference"),
    "legacy": ("s-", "paper: fixed dt, end-point average, dt sweep"),
    "legacy-interp": ("^-", "paper + linear interpolation, dt sweep"),
    "legacy-arcs": ("D-", "paper's q-arc wall, q sweep"),
    "legacy-compiled": ("s--", "paper: fixed dt, compiled (numba) like exact, dt sweep"),
    "ivp": ("v-", "solve_ivp DOP853 + events, rtol sweep"),
}
PANELS = (
    ("time_s", "collision time error (s)"),
    ("point_m", "contact point error (m)"),
    ("energy_rel", "energy error (rel.)"),
)


def matplotlib_missing() -> str | None:
    """None when matplotlib imports, else the reason (the plots are skipped with this message)."""
    try:
        import matplotlib  # noqa: F401
    except ImportError as exc:
        return f"plots skipped: matplotlib is missing ({exc}); install the plot extra: pip install -e '.[plot]'"
    return None


def work_precision_plot(summary: list[dict[str, Any]], path: Path, caption: str) -> Path:
    """Median error against median time per event, log–log, one panel per error measure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import LogFormatterSciNotation, LogLocator, NullFormatter

    fig, axes = plt.subplots(1, len(PANELS), figsize=(15, 4.8), constrained_layout=True)
    for ax, (key, label) in zip(axes, PANELS, strict=True):
        for method, (marker, name) in STYLE.items():
            pts = [
                (s["seconds_per_event"] * 1e3, max(s[f"{key}_median"], ERROR_FLOOR))
                for s in summary
                if s["method"] == method and not s["one_rod_only"] and s["matched"] > 0
            ]
            if pts:
                ax.loglog(*zip(*pts, strict=True), marker, label=name, alpha=0.85)
        ax.set_xlabel("time per event (ms, median over scenes)")
        # one label per decade, none on the minor ticks: the default log labels overlap (issue 17)
        ax.xaxis.set_major_locator(LogLocator(base=10.0, numticks=8))
        ax.xaxis.set_major_formatter(LogFormatterSciNotation(base=10.0))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.tick_params(axis="x", labelsize=8)
        ax.set_ylabel(f"median {label}")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    fig.suptitle(caption, fontsize=9)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

"""``millctl study FILE.toml``: sweep or optimise the operating point and the design (docs/studies.md)."""

from __future__ import annotations

import argparse
import math
import signal
import time
from pathlib import Path
from typing import Any

from millctl.cli.args import positive_int
from millctl.cli.output import print_json, stderr_console, stdout_console
from millctl.cli.priority import add_priority_option, lower_priority
from millctl.errors import ExitCode, InvalidInputError


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``study``."""
    parser = subparsers.add_parser(
        "study",
        help="design study: sweep or optimise the operating point and the mill's design",
        description="Run a study file: parameters on a grid, a list or an optimiser; metrics, constraints, "
        "objective. Resumes from its results file.",
    )
    parser.add_argument("file", help="the study (TOML)")
    parser.add_argument("--out", type=Path,
                        help="results file (.parquet or .csv; default: in ~/.local/state/millctl/studies)")
    parser.add_argument("--csv", action="store_true", help="write CSV instead of Parquet")
    parser.add_argument("--fresh", action="store_true", help="discard an existing results file instead of resuming")
    parser.add_argument("--workers", type=positive_int, help="local worker processes (default: every local core)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="run on this Dask distributed scheduler")
    parser.add_argument("--pareto", metavar="A,B", help="the Pareto front of two metrics (-NAME minimises)")
    parser.add_argument("--figures", metavar="DIR", type=Path, help="write heat map, Pareto and sensitivity PNGs")
    parser.add_argument("--heatmap", metavar="METRIC", help="metric of the heat map (default: the objective's)")
    parser.add_argument("--top", type=positive_int, default=10, help="rows in the table (default 10)")
    parser.add_argument("--recipe", metavar="OUT.toml", type=Path, help="write a pre-flighted recipe at the best point")
    target = parser.add_mutually_exclusive_group()
    target.add_argument("--dose-kj-g", type=float, help="the recipe mills until this dose (kJ per g of powder)")
    target.add_argument("--hold-h", type=float, default=None, help="the recipe mills this long (h; default 1)")
    parser.add_argument("--json", action="store_true", help="machine-readable summary on stdout")
    add_priority_option(parser)
    parser.set_defaults(handler=_run)


def _results_path(args: argparse.Namespace) -> Path:
    """``--out``, else the study's file in the user's state folder (never the working folder: issue 39, 8)."""
    if args.out is not None:
        return Path(args.out)
    from millctl.config.paths import state_dir

    path = state_dir() / "studies" / (Path(args.file).stem + (".csv" if args.csv else ".parquet"))
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _run(args: argparse.Namespace) -> int:
    from millctl.config import load_config
    from millctl.studies import ResultsStore, StudyRunner, check_parameters, load_study, make_backend

    lower_priority(args.no_nice, "the study")
    study = load_study(args.file)
    base_path = (Path(args.file).parent / study.study.config) if study.study.config else args.config
    loaded = load_config(base_path)
    check_parameters(study, loaded.config, args.file)
    runner = StudyRunner(study, loaded.config, args.file)
    store = ResultsStore(_results_path(args), runner.fingerprint)
    store.lock()  # one run per results file: a second is refused with this PID
    try:
        if args.fresh:
            store.reset()
        reused = store.resume()
        runner.store = store
        pareto = _pareto_metrics(args.pareto, runner.metrics)
        err = stderr_console()
        backend = make_backend(args.workers, args.scheduler, *_size(study, runner))
        started = time.perf_counter()
        result = _interruptible(runner, backend, err, study.study.name, store)
    finally:
        store.unlock()
    elapsed = time.perf_counter() - started
    summary = _summary(args, study, loaded.source, store, result, backend, elapsed, reused, pareto)
    summary["fingerprint"] = runner.fingerprint
    if args.figures is not None:
        from millctl.studies.figures import write_figures

        summary["figures"] = write_figures(
            args.figures, study, runner, result, args.heatmap, pareto, summary.get("pareto_front")
        )
    if args.recipe is not None:
        summary["recipe"] = _write_recipe(args, study, runner, result)
    if args.json:
        print_json(args, summary)
    else:
        _print_table(result, runner.metrics, args.top, summary, study)
    return int(ExitCode.OK)


def _pareto_metrics(text: str | None, metrics: tuple[str, ...]) -> list[str] | None:
    if not text:
        return None
    names = [n.strip() for n in text.split(",")]
    bad = [n for n in names if n.lstrip("-") not in metrics]
    if len(names) != 2 or bad:
        raise InvalidInputError(
            f"--pareto {text!r}: give two metrics of the study as A,B (-NAME minimises); study metrics: "
            f"{', '.join(metrics)}"
        )
    return names


def _size(study: Any, runner: Any) -> tuple[int, float]:
    """Points to compute (a grid's pending ones; an optimiser's population per generation) and one's serial cost (s).

    The cost follows the study's levels, revolutions and cam phases (:func:`millctl.studies.backends.point_cost_s`),
    so that workers start only where the benchmark's rule N·c ≥ 4·w·S says they gain.
    """
    from millctl.studies.backends import point_cost_s
    from millctl.studies.metrics import METRICS, needs_slip_run
    from millctl.studies.run import grid_points

    m = study.metrics
    levels = {METRICS[n].level for n in runner.metrics}
    cost = point_cost_s(levels, m.revolutions, m.cam_phases, m.slip_phases, needs_slip_run(runner.metrics))
    if study.is_optimisation:
        settings = study.optimiser
        population = (settings.population if settings is not None else 8) * len(study.parameters)
        return population, cost
    pending = [p for p in grid_points(study) if runner.store is None or _key(p) not in runner.store.rows]
    return len(pending), cost


def _key(params: dict[str, Any]) -> str:
    from millctl.studies.engine import point_key

    return point_key(params)


def _interruptible(runner: Any, backend: Any, console: Any, name: str, store: Any) -> Any:
    """Run the study; on Ctrl+C (SIGINT to the group or to this process) stop the workers at once.

    Every finished batch is already in the results file (the store writes each as it comes);
    the batches running are lost, the rest never start. Says what was saved, then lets the
    interrupt end the command (exit code 130).
    """
    # Ctrl+C must reach the study even where it was started with SIGINT ignored (a background job of a
    # script, a test's subprocess): Python then never installs its KeyboardInterrupt handler by itself
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        result = _with_progress(runner, backend, console, name)
    except KeyboardInterrupt:
        backend.abort()
        console.print(
            f"interrupted: {len(store.rows)} finished points are in {store.path}; run the same command to resume",
            highlight=False,
        )
        raise
    except BaseException:
        backend.abort()
        raise
    finally:
        signal.signal(signal.SIGINT, previous)
    backend.close()
    return result


def _with_progress(runner: Any, backend: Any, console: Any, name: str) -> Any:
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        task = progress.add_task(f"{name} ({backend.name}, {backend.workers} workers)", total=None)

        def update(done: int, total: int) -> None:
            progress.update(task, completed=done, total=total)

        return runner.run(backend, update)


def _clean(row: dict[str, Any] | None) -> dict[str, Any] | None:
    if row is None:
        return None
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items() if k != "key"}


def _summary(
    args: argparse.Namespace,
    study: Any,
    config_source: str,
    store: Any,
    result: Any,
    backend: Any,
    elapsed: float,
    reused: int,
    pareto: list[str] | None,
) -> dict[str, Any]:
    from millctl.studies import pareto_front

    events = sum(int(r["events"]) for r in result.rows)
    data: dict[str, Any] = {
        "study": study.study.name,
        "source": args.file,
        "config": config_source,
        "results": str(store.path),
        "points": len(result.rows),
        "computed": result.computed,
        "reused": reused,
        "feasible": sum(1 for r in result.rows if r["feasible"]),
        "backend": backend.name,
        "workers": backend.workers,
        "elapsed_s": elapsed,
        "points_per_s": result.computed / elapsed if elapsed > 0 else None,
        "events": events,
        "objective": result.objective,
        "metrics": list(result.metrics),
        "best": _clean(result.best),
        "findings": [_clean(f) for f in result.findings],
    }
    if pareto is not None:
        data["pareto"] = pareto
        data["pareto_front"] = [_clean(r) for r in pareto_front(result.rows, pareto)]
    return data


def _print_table(result: Any, metrics: tuple[str, ...], top: int, summary: dict[str, Any], study: Any) -> None:
    from millctl.cli.tables import Column, print_table
    from millctl.studies.metrics import quantity_label

    out = stdout_console()
    params = [k for k in (result.best or result.rows[0]) if k in _param_columns(result.rows)]
    ranked = sorted((r for r in result.rows if math.isfinite(r["objective"])), key=lambda r: -r["objective"])[:top]

    def column(header: str, rows: list[dict[str, Any]], key: str) -> Column:
        return Column(header, tuple(_fmt(r.get(key)) for r in rows))

    def quantities(rows: list[dict[str, Any]], names: list[str]) -> list[Column]:
        return [column(quantity_label(n), rows, n.lstrip("-")) for n in names]

    print_table(
        out,
        f"{summary['study']}: best {len(ranked)} of {summary['feasible']} feasible points",
        [column("point", ranked, "point"), *quantities(ranked, params),
         column(_objective_header(study), ranked, "objective"), *quantities(ranked, list(metrics))],
    )
    if "pareto_front" in summary:
        front = summary["pareto_front"]
        ways = " and ".join(f"{quantity_label(n)}, {'lower' if n.startswith('-') else 'higher'} is better"
                            for n in summary["pareto"])
        print_table(out, f"Pareto front of {ways}",
                          [column("point", front, "point"), *quantities(front, params),
                           *quantities(front, summary["pareto"])])
    if summary["findings"]:
        found = summary["findings"]
        apart = ("point", "value", "criterion", "caveat")
        names = [k for k in found[0] if k not in apart]
        names += list(dict.fromkeys(k for f in found for k in f if k not in names and k not in apart))
        criteria = Column("criterion", tuple(
            "the objective" if f["criterion"] == "objective" else quantity_label(f["criterion"])
            for f in found))
        print_table(out, "findings: the best feasible point of each group, by each criterion",
                          [criteria, *quantities(found, names), column("point", found, "point"),
                           column("value of the criterion", found, "value")])
        for caveat in dict.fromkeys(f["caveat"] for f in found if f.get("caveat")):
            out.print(f"caveat: {caveat}", markup=False)
    rate = summary["points_per_s"]
    stderr_console().print(
        f"{summary['points']} points ({summary['computed']} computed, {summary['reused']} from {summary['results']}), "
        f"{summary['feasible']} feasible; {summary['backend']} × {summary['workers']}; "
        f"{summary['elapsed_s']:.1f} s" + (f", {rate:.2f} points/s" if rate else ""),
        markup=False,
    )


def _objective_header(study: Any) -> str:
    """What the objective column holds, in words with the unit: the metric, its negative, or the weighted sum."""
    from millctl.studies.metrics import quantity_label

    objective = study.objective
    if objective.maximize is not None:
        return f"objective: {quantity_label(objective.maximize)}"
    if objective.minimize is not None:
        return f"objective: −{quantity_label(objective.minimize)}, maximised"
    terms = " + ".join(f"{w:g} × {quantity_label(m)}" for m, w in objective.terms.items())
    return f"objective: {terms}, maximised"


_NOT_PARAMS = frozenset({"point", "key", "events", "feasible", "violations", "objective"})


def _param_columns(rows: list[dict[str, Any]]) -> set[str]:
    from millctl.studies.metrics import METRICS

    return {k for k in rows[0] if k not in _NOT_PARAMS and k not in METRICS} if rows else set()


def _fmt(value: Any) -> str:
    if value is None:
        return "—"
    if isinstance(value, float):
        if not math.isfinite(value):
            return "—"
        return f"{value:.4g}"
    return str(value)


def _write_recipe(args: argparse.Namespace, study: Any, runner: Any, result: Any) -> dict[str, Any]:
    from millctl.studies.recipe import write_recipe

    if result.best is None:
        raise InvalidInputError(f"{args.file}: no feasible point, so no recipe (see the violations in the results)")
    written: dict[str, Any] = write_recipe(
        args.recipe, study, runner, result.best, dose_kj_g=args.dose_kj_g, hold_h=args.hold_h
    )
    return written


__all__ = ["register"]

"""`pmsm-hil sweep SWEEP.yaml --out DIR`: a profile over parameter grids and random draws, on Dask;
`pmsm-hil sweep report DIR`: plots of the metrics against the axes."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from pmsm_hil.cli.errors import SCHEDULER_ERRORS, fail, scheduler_failed


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "sweep",
        help="run a profile over grids / random draws of parameters on Dask; "
        "`sweep report DIR` plots the results",
        description="Runs every point of SWEEP (a sweep YAML, docs/sweep.md) on the "
        "in-process emulator, on a local Dask cluster (one worker per core) "
        "or the scheduler given; one row per run in DIR/results.parquet and "
        "DIR/results.csv. A sweep run again into the same DIR skips the runs "
        "done there. `pmsm-hil sweep report DIR` writes the plots.",
    )
    p.add_argument(
        "sweep",
        metavar="SWEEP",
        help="sweep YAML, or the name of a shipped one (`pmsm-hil profiles`), e.g. tolerance "
        "(or `report` followed by the sweep's DIR)",
    )
    p.add_argument(
        "dir",
        nargs="?",
        default=None,
        metavar="DIR",
        help="with `report`: the sweep's output folder",
    )
    p.add_argument("--out", "-o", default=None, help="output folder (default: sweeps-out/NAME)")
    p.add_argument("--limit", type=int, default=None, metavar="N", help="run only the first N runs")
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDR",
        help="Dask scheduler address, e.g. tcp://HOST:8786 (default: a local cluster)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes of the local cluster (default: one per core)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def report_parser() -> argparse.ArgumentParser:
    """`pmsm-hil sweep report --help`: the report's own usage (argparse would print the sweep's,
    `report` being a value of its SWEEP argument)."""
    p = argparse.ArgumentParser(
        prog="pmsm-hil sweep report",
        description="Writes the report of a sweep's results into DIR/report/: summary.md (per "
        "metric: runs, median, worst, min, max over the completed runs), a plot per metric "
        "against each axis (pass: dot, fail: cross) and, for two grid axes, pass_map.png (the "
        "share of runs passed in each cell); prints the table of the metrics (docs/sweep.md).",
    )
    p.add_argument("dir", metavar="DIR", help="the sweep's output folder (its --out)")
    return p


def asks_report_help(argv: list[str]) -> bool:
    """``sweep report ... --help`` (and no file named ``report`` here, which would be a sweep)."""
    return (
        argv[:2] == ["sweep", "report"]
        and any(a in ("-h", "--help") for a in argv[2:])
        and not os.path.isfile("report")
    )


def main(args: argparse.Namespace) -> int:
    if args.sweep == "report" and not os.path.isfile("report"):
        return _report(args)
    if args.dir is not None:
        return fail(
            "error", f"unexpected argument {args.dir!r} (the output folder is --out DIR)", 2
        )
    from pmsm_hil.profiles import ProfileError
    from pmsm_hil.profiles.shipped import resolve
    from pmsm_hil.sweep import load_sweep, plan_runs, run_sweep
    from pmsm_hil.sweep.results import ResultsFormatError

    if args.limit is not None and args.limit < 1:
        return fail("error", f"--limit = {args.limit} must be >= 1", 2)
    if args.workers is not None and args.workers < 1:
        return fail("error", f"--workers = {args.workers} must be >= 1", 2)
    try:
        sweep = load_sweep(resolve(args.sweep, "sweep"), defer=True)
        runs = plan_runs(sweep)
    except ProfileError as e:
        return fail("error", str(e), 2)
    out = Path(args.out or Path("sweeps-out") / sweep.name)
    from pmsm_hil.cli.paths import folder_problem

    problem = folder_problem(out)
    if problem:  # before the cluster starts, and not taken for a scheduler that cannot be reached
        return fail("error", f"--out {out}: {problem}", 2)
    print(
        f"sweep {sweep.name}: {len(runs)} runs of {Path(sweep.profile_path).name}"
        + (f", the first {min(args.limit, len(runs))}" if args.limit else "")
        + f" -> {out}/ on "
        + (args.scheduler or _local(args.workers or os.cpu_count() or 1))
    )
    try:
        res = run_sweep(
            sweep,
            out,
            limit=args.limit,
            scheduler=args.scheduler,
            workers=args.workers,
            progress=not args.no_progress,
            runs=runs,
        )
    except ResultsFormatError as e:
        return fail("error", str(e), 2)
    except SCHEDULER_ERRORS as e:
        return scheduler_failed(args.scheduler, e)
    ran, *judged = res.end_lines()
    print(ran)
    for r in res.rows:
        if r.get("status") == "interrupted":
            kept = f"its log {r['log_path']} holds" if r.get("log_path") else "no log kept of"
            print(f"  run {r['index']} ({r['key']}) stopped: {kept} what it ran")
        elif r.get("status") != "ok":
            print(f"  run {r['index']} ({r['key']}) failed to run: {r.get('error', '')}")
    for line in judged:
        print(line)
    print(f"results {res.parquet}\n        {res.csv}")
    if res.interrupted:
        return 130
    return 0  # failed runs are results (status "failed" in the table), not a failed sweep


def _local(n: int) -> str:
    return f"a local cluster ({n} worker{'s' if n != 1 else ''})"


def _report(args: argparse.Namespace) -> int:
    from pmsm_hil.sweep.report import ReportError, write_report

    if args.dir is None:
        return fail(
            "error", "sweep report needs the sweep's output folder: pmsm-hil sweep report DIR", 2
        )
    try:
        report = write_report(Path(args.dir))
    except ReportError as e:
        return fail("error", str(e), 2)
    _print_report(report)
    return 0


def _print_report(report) -> None:
    """The metrics' median and worst over the completed runs, the pass count, the files."""
    from rich import box
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from pmsm_hil.sweep.report import stat_text

    console = Console()
    if not console.is_terminal:
        console = Console(width=max(console.width, 100))
    for note in report.notes:
        console.print(f"[yellow]note:[/] {escape(note)}", highlight=False)
    tab = Table(
        title=f"{report.out} (over the completed runs)",
        title_justify="left",
        header_style="bold",
        box=box.SIMPLE_HEAD,
    )
    for col in ("metric", "runs", "median", "worst"):
        tab.add_column(col, justify="left" if col == "metric" else "right")
    for m in report.stats:
        tab.add_row(
            m.metric, m.runs_text(), stat_text(m.metric, m.median), stat_text(m.metric, m.worst)
        )
    console.print(tab)
    console.print(report.headline(), highlight=False, soft_wrap=True)
    for i, err in report.failed[:5]:
        console.print(f"  run {i} failed to run: {escape(err)}", highlight=False, soft_wrap=True)
    if len(report.failed) > 5:
        console.print(f"  and {len(report.failed) - 5} more (summary.md)", highlight=False)
    plots = [p for p in report.files if p.suffix == ".png"]
    console.print(
        f"report {report.files[0]}"
        + (f" and {len(plots)} plots in {plots[0].parent}/" if plots else ""),
        highlight=False,
        soft_wrap=True,
    )

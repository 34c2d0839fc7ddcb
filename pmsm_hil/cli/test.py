"""`pmsm-hil test PROFILES...`: run profiles on the emulator and judge them against their
acceptance criteria; a pass/fail table, JUnit XML, a non-zero exit on any failure."""

from __future__ import annotations

import argparse
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from pmsm_hil.cli.errors import SCHEDULER_ERRORS, fail, report, scheduler_failed
from pmsm_hil.cli.paths import folder_problem
from pmsm_hil.seeds import seed_arg

EXIT_FAILED = 1
EXIT_INTERRUPTED = 130  # as `run`: Ctrl-C, SIGTERM or SIGHUP; the motor was stopped


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "test",
        help="run profiles and check their acceptance criteria (regression suite)",
        description="Runs each PROFILE on the in-process emulator (several on Dask) and "
        "checks the run against the profile's `acceptance:` section (without "
        "one: the whole profile played, no fault). Prints a pass/fail table "
        "with the measured value beside each bound; exits 1 on any failure.",
    )
    p.add_argument(
        "profiles", nargs="+", metavar="PROFILE", help="profile YAML files or shipped names"
    )
    p.add_argument(
        "--rig", default=None, help="rig file (or shipped name) instead of each profile's"
    )
    p.add_argument(
        "--motor",
        default=None,
        help="motor file (or shipped name) instead of each profile's, e.g. a commissioned one",
    )
    p.add_argument("--seed", type=seed_arg, default=1, help="emulator noise seed (default 1)")
    p.add_argument("--junit", default=None, metavar="OUT.xml", help="also write JUnit XML here")
    p.add_argument(
        "--out",
        "-o",
        default=None,
        help="folder for the logs and the results table (default: a temporary folder, removed)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes when there are several profiles (default: one per core)",
    )
    p.add_argument(
        "--scheduler", default=None, metavar="ADDR", help="Dask scheduler address (default: local)"
    )


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.log.write_support import signals_held

    def junit(text: str) -> bool:
        """Write the report if asked; False (the error printed) when it cannot be written."""
        if not args.junit:
            return True
        try:
            Path(args.junit).write_text(text, encoding="utf-8")
        except OSError as e:  # checked before the run, but a disk fills or a folder goes
            fail("error", f"--junit {args.junit}: cannot be written ({e.strerror or e})", 2)
            return False
        print(f"JUnit XML {args.junit}")
        return True

    if args.workers is not None and args.workers < 1:
        return fail("error", f"--workers {args.workers}: must be at least 1", 2)
    if args.junit:  # checked before the suite runs, not after it
        problem = _junit_problem(Path(args.junit))
        if problem:
            return fail("error", f"--junit {args.junit}: {problem}", 2)
    try:
        with signals_held():  # Ctrl-C while the suite module imports (0.3 s) is raised after it
            import pmsm_hil.sweep.suite  # noqa: F401  (a second import of numpy would fail)
        return _suite(args, junit)
    except KeyboardInterrupt:  # before the runs could say so themselves (loading, a cluster)
        from pmsm_hil.sweep.suite import junit_error

        # a report from an earlier suite must not stand for this one in CI
        why = "interrupted before the suite's results were written: no profile judged"
        junit(junit_error("interrupted", why))
        report("stopped", why)
        return EXIT_INTERRUPTED


def _suite(args: argparse.Namespace, junit: Callable[[str], bool]) -> int:
    from pmsm_hil.profiles import ProfileError
    from pmsm_hil.profiles.shipped import resolve
    from pmsm_hil.sweep.suite import junit_error, junit_xml, plan_suite, run_suite

    try:
        profiles, problems = [], []
        for name in args.profiles:  # every name that finds no file is named, with the bad files
            try:
                profiles.append(resolve(name, "profile"))
            except ProfileError as e:
                problems += e.problems
        rig = resolve(args.rig, "rig") if args.rig else None
        motor = resolve(args.motor, "motor") if args.motor else None
        try:
            cases = plan_suite(profiles, seed=args.seed, rig=rig, motor=motor)
        except ProfileError as e:
            problems += e.problems
        if problems:
            raise ProfileError(problems)
    except ProfileError as e:
        junit(junit_error("inputs", str(e)))
        return fail("error", str(e), 2)
    problem = folder_problem(Path(args.out)) if args.out is not None else None
    if problem:  # before the run, and not taken for a scheduler that cannot be reached
        junit(junit_error("inputs", f"--out {args.out}: {problem}"))
        return fail("error", f"--out {args.out}: {problem}", 2)
    tmp = None
    if args.out is None:
        tmp = tempfile.TemporaryDirectory(prefix="pmsm-hil-test-")
        out = Path(tmp.name)
    else:
        out = Path(args.out)
    try:
        run_suite(
            cases,
            out,
            workers=args.workers,
            scheduler=args.scheduler,
            keep_logs=args.out is not None,
            progress=len(cases) > 1,
        )
    except SCHEDULER_ERRORS as e:
        junit(junit_error("scheduler", f"{args.scheduler}: {type(e).__name__}: {e}"))
        return scheduler_failed(args.scheduler, e)
    finally:
        if tmp is not None:
            tmp.cleanup()
    _print(cases)
    interrupted = sum(c.status == "interrupted" for c in cases)
    if args.out is None and not all(c.passed for c in cases) and not interrupted:
        print("the logs were not kept: --out DIR keeps them (and the results table) to look into")
    if not junit(junit_xml(cases)):
        return 2  # CI would find no report: not a pass, whatever the checks said
    if interrupted:
        report("stopped", f"interrupted: {interrupted} of {len(cases)} profiles not judged")
        return EXIT_INTERRUPTED
    return 0 if all(c.passed for c in cases) else EXIT_FAILED


def _print(cases) -> None:
    from rich import box
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    console = Console()
    if not console.is_terminal:
        console = Console(width=max(console.width, 120))
    for c in cases:
        for w in c.warnings:
            console.print(f"[yellow]warning:[/] {escape(w)}", highlight=False, soft_wrap=True)
        tab = Table(
            title=escape(f"{c.name} ({c.profile}, seed {c.run.seed})" if c.run else c.name),
            title_justify="left",
            header_style="bold",
            box=box.SIMPLE_HEAD,
        )
        for col in ("scope", "criterion", "measured", "bound", "result"):
            tab.add_column(col, justify="right" if col in ("measured", "bound") else "left")
        for ch in c.checks:
            tab.add_row(
                escape(ch["scope"]),
                escape(ch["criterion"]),
                escape(ch["measured"]),
                escape(ch["bound"]),
                "[green]pass[/]" if ch["passed"] else "[red]FAIL[/]",
            )
        if not console.is_terminal:  # a CI log: each check on one line, however long its names
            unbounded = console.options.update_width(10_000)
            console.width = max(console.width, console.measure(tab, options=unbounded).maximum)
        console.print(tab if c.checks else tab.title)  # no checks: the title, no empty table
        if c.default_criteria:
            console.print(
                "[dim]no acceptance criteria in the profile: the default (whole profile, no fault)[/]"
            )
        if c.status == "interrupted":
            console.print(f"[yellow]{escape(c.error)}[/]", highlight=False, soft_wrap=True)
        elif c.status != "ok":
            console.print(f"[red]run failed:[/] {escape(c.error)}")
        for hint in c.hints():
            console.print(f"[yellow]hint:[/] {escape(hint)}", highlight=False, soft_wrap=True)
        n_fail = sum(1 for ch in c.checks if not ch["passed"])
        verdict = "[green]PASS[/]" if c.passed else "[red]FAIL[/]"
        if c.status == "interrupted":
            console.print(
                f"[yellow]NOT JUDGED[/] {escape(c.name)}: interrupted"
                + (f"; its log so far {c.log_path}" if c.log_path else ""),
                highlight=False,
                soft_wrap=True,
            )
            console.print()
            continue
        console.print(
            f"{verdict} {escape(c.name)}: {len(c.checks) - n_fail} of {len(c.checks)} checks passed"
            + (f"; log {c.log_path}" if c.log_path else ""),
            highlight=False,
            soft_wrap=True,
        )
        console.print()
    n_pass = sum(c.passed for c in cases)
    console.print(f"{n_pass} of {len(cases)} profiles passed", highlight=False)


def _junit_problem(path: Path) -> str | None:
    """Why the JUnit report could not be written at ``path`` (its folder is made if missing)."""
    if path.is_dir():
        return "is a folder; give a file name, e.g. report.xml"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        return f"cannot make its folder ({e.strerror})"
    if not os.access(path.parent, os.W_OK):
        return f"its folder {path.parent} is not writable"
    return None

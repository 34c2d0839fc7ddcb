"""`pmsm-hil analyze LOG.mcap`: per-segment summary of a run log."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

from pmsm_hil.cli.errors import fail

if TYPE_CHECKING:
    from pmsm_hil.analysis.identification import IdentTable
    from pmsm_hil.log.reader import Log


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "analyze",
        help="summarise a run log (per segment: speed error, ripple, faults)",
        description="Per-segment summary of a run log, and the identification table "
        "when estimators ran. Exit 0: the whole run is in the log and "
        "within bounds; 1: bounds missed, or the log is incomplete "
        "(truncated, interrupted, segments missing); 2: not a log.",
    )
    p.add_argument("log", help="MCAP log written by `pmsm-hil run`")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")


def identification(path: Path | str, log: Log | None = None) -> IdentTable | None:
    """The identification table of a log, or None when no estimator ran."""
    from pmsm_hil.analysis.identification import identification_table

    try:
        t = identification_table(path, log=log)
    except (KeyError, ValueError):
        return None
    return t if t.cells else None


def print_identification(table: IdentTable) -> None:
    from pmsm_hil.analysis.identification import text_table

    print()
    print(text_table(table))


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.analysis.reading import other_kind, read_for_analysis, recover_hint
    from pmsm_hil.analysis.summary import summarize_log
    from pmsm_hil.analysis.summary_text import print_summary
    from pmsm_hil.log.reader import LogFormatError, path_problem

    path = Path(args.log)
    why = path_problem(args.log)
    if why:
        return fail("error", why, 2)
    try:
        log = read_for_analysis(path)
    except (LogFormatError, ValueError, OSError) as e:
        return fail("error", f"{path}: not a readable pmsm-hil log ({e})", 2)
    kind = other_kind(log)
    if kind and "/pmsm/commission" in log.topics:
        return _commissioning(path)
    if kind:
        return fail("error", f"{path}: {kind}", 2)
    recover = recover_hint(path)
    if not log.counts.get("/pmsm/telemetry"):
        return fail(
            "error",
            f"{path}: no telemetry in the log (empty, or cut off before the first chunk): "
            f"nothing to analyze{recover}",
            2,
        )
    try:
        summary = summarize_log(path, log)
    except (LogFormatError, ValueError, OSError) as e:
        return fail("error", f"{path}: not a readable pmsm-hil log ({e})", 2)
    ident = identification(path, log)
    if args.json:
        d = summary.as_dict()
        if ident is not None:
            d["identification"] = ident.as_dict()
        from pmsm_hil.gap.report import jsonable  # NaN and infinity as null: JSON has neither

        print(json.dumps(jsonable(d), indent=2, allow_nan=False))
    else:
        print_summary(summary)
        if ident is not None:
            print_identification(ident)
        if recover and not log.finalised:
            print(f"note: the log was not finished{recover}")
    return 0 if summary.ok else 1


def _commissioning(path: Path) -> int:
    """A commissioning run's log: each step's status and results, as `commission` printed them
    (exit 0 when every step passed, 1 otherwise)."""
    from pmsm_hil.commission.steps import STEP_TITLES, logged_steps
    from pmsm_hil.log.reader import read_log

    steps = logged_steps(read_log(path, topics=["/pmsm/commission"]))
    print(f"{path}: a commissioning run (pmsm-hil commission), {len(steps)} steps logged")
    for step, status, q in steps:
        print(f"  {STEP_TITLES.get(step, step)}: {status}")
        for name, m in q.items():
            print(f"      {name:<26} {m.text()}")
    print("its motor file's `commissioning:` section holds the results (docs/commissioning.md)")
    return 0 if steps and all(status == "ok" for _, status, _ in steps) else 1

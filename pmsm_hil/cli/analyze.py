"""`pmsm-hil analyze LOG.mcap`: per-segment summary of a run log."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from pmsm_hil.cli.errors import fail


def add_parser(sub) -> None:
    p = sub.add_parser("analyze", help="summarise a run log (per segment: speed error, ripple, faults)")
    p.add_argument("log", help="MCAP log written by `pmsm-hil run`")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")


def main(args: argparse.Namespace) -> int:
    from pmsm_hil.analysis.summary import print_summary, summarize_log

    path = Path(args.log)
    if not path.exists():
        return fail("error", f"{path}: no such file", 2)
    try:
        summary = summarize_log(path)
    except Exception as e:
        return fail("error", f"{path}: not a readable pmsm-hil log ({e})", 2)
    ident = None
    try:
        from pmsm_hil.analysis.identification import identification_table
        t = identification_table(path)
        ident = t if t.cells else None
    except (KeyError, ValueError):
        ident = None
    if args.json:
        d = summary.as_dict()
        if ident is not None:
            d["identification"] = ident.as_dict()
        print(json.dumps(d, indent=2))
    else:
        print_summary(summary)
        if ident is not None:
            from pmsm_hil.analysis.identification import text_table
            print()
            print(text_table(ident))
    return 0
